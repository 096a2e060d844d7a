"""The reflex pathway, the position-dependent joint and the slow-movement perturbation in the simulators
(sims/reflex_stretch.py, sims/joint_position_dependent.py, sims/perturbation_moving.py), integrated by the
analytic time-stepping path (sims/backend_stepping.py) and by MuJoCo (sims/backend_mujoco_stepping.py)."""
from __future__ import annotations

import numpy as np
import pytest

from jointbench import sims
from jointbench.core.errors import ConfigError
from jointbench.sims import Experiment, simulate
from jointbench.sims.apparatus import PositionServo, TorqueDrive
from jointbench.sims.backend_stepping import SteppingBackend
from jointbench.sims.joint_position_dependent import PositionDependentJoint
from jointbench.sims.joint_second_order import SecondOrderJoint
from jointbench.sims.reflex_stretch import ReflexStepper, StretchReflex

ANKLE = {"model": "second_order", "I": 0.015, "B": 0.8, "K": 120}
PD_ANKLE = {"model": "position_dependent", "I": 0.015, "B": 0.8, "K": {"polynomial": [100, 150, 200]},
            "angle_range": [-0.6, 0.4]}
PRALDS = {"kind": "pralds", "rms": 0.02, "min_hold": "20 ms", "max_hold": "200 ms", "smoothing": "20 Hz"}
MOVING = {"kind": "moving", "movement": {"shape": "sine", "mean": -0.1, "amplitude": 0.3, "frequency": 0.1},
          "perturbation": PRALDS}


def vaf(y, yhat):
    return 100.0 * (1.0 - np.var(y - yhat) / np.var(y))


def experiment(joint=ANKLE, reflex=None, apparatus=None, perturbation=PRALDS, fs_sim=2000, duration=10.0,
               backend="analytic", acquisition=None):
    j = dict(joint)
    if reflex is not None:
        j["reflex"] = reflex
    return Experiment.from_mapping({"joint": j,
                                    "apparatus": apparatus or {"kind": "position_servo", "stiffness": 30000},
                                    "perturbation": perturbation, "fs_sim": fs_sim, "duration": duration,
                                    "acquisition": acquisition or {"detrend": False}}, "test", backend=backend)


# ------------------------------------------------------------------------------------------- the pathway
def test_half_wave_reflex_resists_stretch_only():
    r = StretchReflex(gain=4.0, delay=0.01, damping_ratio=1.0)
    v = np.sin(2 * np.pi * np.arange(2000) / 400)           # 2.5 Hz at 1 kHz: stretch half the time
    T = r.torque(v, 1000.0)
    # rectified, then a critically damped unit-gain low-pass (impulse response >= 0): never below 0
    assert T.min() >= -1e-12 and T.max() > 0.5
    neg = StretchReflex(gain=4.0, delay=0.01, damping_ratio=1.0, stretch="negative").torque(v, 1000.0)
    assert neg.max() <= 1e-12
    assert np.allclose(neg, -StretchReflex(gain=4.0, delay=0.01, damping_ratio=1.0).torque(-v, 1000.0))
    lin = StretchReflex(gain=4.0, delay=0.01, nonlinearity="none")
    assert np.allclose(lin.torque(-v, 1000.0), -lin.torque(v, 1000.0))   # linear: odd
    # the delay: nothing before it, the static gain G once settled
    step = np.ones(3000)
    Ts = StretchReflex(gain=2.0, delay=0.05, frequency=5.0).torque(step, 1000.0)
    assert np.all(Ts[:50] == 0) and Ts[51] > 0 and Ts[-1] == pytest.approx(2.0, rel=1e-6)


def test_stepper_does_not_depend_on_the_windows():
    r = StretchReflex(gain={"shape": "sine", "mean": 3, "amplitude": 2, "period": 1.0}, delay=0.0173)
    v = np.random.default_rng(1).standard_normal(5000)
    whole = r.torque(v, 1000.0)
    st = ReflexStepper(r, 1000.0, len(v))
    k = 0
    for w in (1, 7, 17, 3, 17, 200, 17):
        k += w
        st.advance(k, v)
    st.advance(len(v), v)
    assert np.allclose(st.torque, whole, rtol=0, atol=1e-12)


def test_time_varying_gain_switches_the_reflex_torque_off():
    e = experiment(reflex={"gain": {"shape": "square", "mean": 2.5, "amplitude": 2.5, "period": 4.0}, "delay": "40 ms",
                           "frequency": "3 Hz"})
    tr = simulate(e, 0)
    g, T = tr.truth.signals["reflex_gain"], tr.truth.signals["reflex_torque"]
    on = (tr.time > 0.5) & (tr.time < 1.9)
    off = (tr.time > 2.8) & (tr.time < 3.9)                  # gain 0 from 2 s, the torque decays within 0.8 s
    assert np.all(g[on] == 5.0) and np.all(g[off] == 0.0)
    assert np.std(T[on]) > 20 * np.std(T[off])


def test_truth_states_each_part():
    tr = simulate(experiment(reflex={"gain": 5, "delay": "40 ms"}), 2)
    s = tr.truth.signals
    assert np.allclose(s["intrinsic_torque"] + s["reflex_torque"], s["torque"], atol=1e-9)
    assert tr.truth.K == 120.0                             # the truth's K is the intrinsic stiffness
    assert 0.1 < np.std(s["reflex_torque"]) / np.std(s["torque"]) < 0.6


# ----------------------------------------------------------------------------------- the stepping path
def test_no_reflex_torque_is_backend_ltv_to_rounding():
    e0, e1 = experiment(), experiment(reflex={"gain": 0, "delay": "40 ms"})
    a, b = simulate(e0, 5, backend="ltv"), simulate(e1, 5)
    assert sims.BACKENDS.get("analytic")().chosen(e1) == "stepping"
    assert np.max(np.abs(a.angle - b.angle)) < 1e-14 * 1e3
    assert np.max(np.abs(a.torque - b.torque)) < 1e-9 * np.max(np.abs(a.torque))


def _fine(joint, app, drive, fs, m, reflex):
    n = len(drive)
    t = np.arange(n) / fs
    tf = np.arange((n - 1) * m + 1) / (fs * m)
    r = SteppingBackend().run(joint, app, np.interp(tf, t, drive), np.zeros(len(tf)), fs * m, reflex=reflex)
    return r.angle[::m], r.torque_measured[::m], r.torque_parts["reflex_torque"][::m]


@pytest.mark.parametrize("joint", ["linear", "position_dependent"])
def test_stepping_converges_to_a_fine_reference(joint):
    """The scheme against the same trial at 16x the rate (the drive held linearly between the coarse samples,
    which is what the coarse step assumes): second order, and 1 kHz already within 1e-3 of the reference."""
    fs, n = 1000.0, 8000
    rng = np.random.default_rng(0)
    drive = sims.PERTURBATIONS.get("pralds")(rms=0.02, min_hold=0.02, max_hold=0.2, smoothing=20.0).generate(n, fs, rng)
    if joint == "linear":
        j = SecondOrderJoint(0.015, 0.8, 120.0)
    else:
        j = PositionDependentJoint(I=0.015, K={"polynomial": [100, 150, 200]}, B=0.8, angle_range=(-0.6, 0.4))
        drive = drive + 0.3 * np.sin(2 * np.pi * 0.1 * np.arange(n) / fs)
    reflex = StretchReflex(gain=5.0, delay=0.04)
    ref = _fine(j, PositionServo(stiffness=30000.0), drive, fs, 16, reflex)
    err = {}
    for m in (1, 2):
        out = _fine(j, PositionServo(stiffness=30000.0), drive, fs, m, reflex)
        err[m] = [np.sqrt(np.mean((o - r) ** 2)) / np.std(r) for o, r in zip(out, ref)]
    assert max(err[1]) < 1e-3                   # angle, torque, reflex torque: relative rms error at 1 kHz
    assert all(e1 > 3.0 * e2 for e1, e2 in zip(err[1], err[2]))    # halving the step: about 4x smaller


def test_torque_driven_position_dependent_joint_converges():
    fs, n = 1000.0, 4000
    t = np.arange(n) / fs
    torque = 5 * np.sin(2 * np.pi * 0.3 * t) + np.random.default_rng(2).standard_normal(n)
    j = PositionDependentJoint(I=0.015, K={"angle": [-0.5, 0.0, 0.5], "value": [40, 100, 260]}, B=0.8)
    a = SteppingBackend().run(j, TorqueDrive(), torque, np.zeros(n), fs)
    b = SteppingBackend().run(j, TorqueDrive(), np.interp(np.arange(8 * (n - 1) + 1) / (8 * fs), t, torque),
                              np.zeros(8 * (n - 1) + 1), 8 * fs)
    assert vaf(b.angle[::8], a.angle) > 99.99


def test_elastic_torque_integrates_the_stiffness():
    for K in ({"polynomial": [100, 150, 200]}, {"angle": [-0.5, 0.0, 0.3], "value": [60, 100, 140]}):
        j = PositionDependentJoint(I=0.015, K=K, damping_ratio=0.3, angle_range=(-0.5, 0.3))
        x = np.linspace(-0.8, 0.6, 14001)
        P = j.elastic_torque(x)
        assert j.elastic_torque(np.zeros(1))[0] == 0.0
        assert np.allclose(np.gradient(P, x), j.stiffness_at(x), rtol=2e-3, atol=0.05)
        assert j.stiffness_at(np.array([0.9]))[0] == j.stiffness_at(np.array([0.3]))[0]    # held outside


def test_position_dependent_truth_follows_the_angle():
    e = experiment(joint=PD_ANKLE, perturbation=MOVING, duration=12.0,
                   acquisition={"detrend": False, "fs": "100 Hz", "trim": "1 s"})
    tr = simulate(e, 1)
    K_expect = 100 + 150 * tr.truth.signals["angle"] + 200 * tr.truth.signals["angle"] ** 2
    assert np.max(np.abs(tr.truth.K - K_expect)) < 0.5        # the acquired angle went through the FIR
    sched = tr.truth.signals["scheduling"]
    assert np.ptp(sched) > 0.55 and np.max(np.abs(sched - tr.angle)) < 0.1   # the slow movement, followed


# -------------------------------------------------------------------------------------- the two backends
@pytest.mark.parametrize("case", ["ankle", "wrist", "position_dependent"])
def test_reflex_agrees_between_analytic_and_mujoco(case):
    """Acceptance: >= 99.9 % VAF of the torque (and of the reflex torque) between the backends."""
    pytest.importorskip("mujoco")
    kw = {"ankle": dict(reflex={"gain": 5, "delay": "40 ms"}, fs_sim=5000),
          "wrist": dict(joint={"model": "wrist_contact", "I": "3 g.m2", "b": 0.035, "k": 5.6},
                        reflex={"gain": 0.3, "delay": "40 ms"}, apparatus={"kind": "handle"}, fs_sim=2500),
          "position_dependent": dict(joint=PD_ANKLE, perturbation=MOVING, reflex={"gain": 3, "delay": "40 ms"},
                                     fs_sim=5000)}[case]
    acq = {"detrend": False, "fs": "100 Hz", "trim": "1 s"}
    a = simulate(experiment(duration=8.0, acquisition=acq, **kw), 3)
    m = simulate(experiment(duration=8.0, acquisition=acq, backend="mujoco", **kw), 3)
    assert vaf(a.torque, m.torque) >= 99.9
    assert vaf(a.truth.signals["reflex_torque"], m.truth.signals["reflex_torque"]) >= 99.9
    assert np.allclose(m.truth.signals["intrinsic_torque"] + m.truth.signals["reflex_torque"],
                       m.truth.signals["torque"], atol=1e-9)


@pytest.mark.parametrize("backend", ["analytic", "mujoco"])
def test_reflex_trials_are_deterministic(backend):
    if backend == "mujoco":
        pytest.importorskip("mujoco")
    e = experiment(reflex={"gain": 3, "delay": "35 ms"}, duration=3.0, backend=backend)
    a, b, c = simulate(e, 1), simulate(e, 1), simulate(e, 2)
    assert np.array_equal(a.torque, b.torque) and not np.array_equal(a.torque, c.torque)


# ------------------------------------------------------------------------------------------- bad input
@pytest.mark.parametrize("reflex, match", [
    ({"gain": 1, "delay": "0.1 ms"}, "shorter than 1 simulation step"),
    ({"gain": -1}, "a reflex gain must stay >= 0"),
    ({"pathway": "tendon", "gain": 1}, "unknown reflex pathway 'tendon'; known: stretch"),
    ({"gain": 1, "colour": "red"}, "unknown key 'colour'"),
    ({"delay": "40 ms"}, "missing required key 'gain'"),
])
def test_bad_reflex_is_one_line(reflex, match):
    with pytest.raises(ConfigError, match=match) as info:
        experiment(reflex=reflex)
    assert "\n" not in str(info.value)


def test_linear_backends_refuse_a_nonlinear_plant():
    for name in ("lti", "ltv"):
        msg = f"backend '{name}' integrates a linear plant; this experiment has a reflex"
        with pytest.raises(ConfigError, match=msg):
            experiment(reflex={"gain": 1}, backend=name)
    with pytest.raises(ConfigError, match="position_dependent"):
        experiment(joint=PD_ANKLE, backend="ltv")


@pytest.mark.parametrize("joint, match", [
    ({**PD_ANKLE, "K": {"polynomial": [10, 150]}}, "K\\(theta\\) reaches .* it must stay > 0"),
    ({**PD_ANKLE, "angle_range": None}, "needs the angle range"),
    ({**PD_ANKLE, "K": {"angle": [0, -1], "value": [1, 2]}}, "must increase strictly"),
    ({**PD_ANKLE, "damping_ratio": 0.3}, "exactly one of 'B'"),
])
def test_bad_position_dependent_joint_is_one_line(joint, match):
    joint = {k: v for k, v in joint.items() if v is not None}
    with pytest.raises(ConfigError, match=match):
        experiment(joint=joint)
