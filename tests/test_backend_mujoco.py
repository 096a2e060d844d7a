"""The MuJoCo backend: the library choice, the models against their config, agreement with the analytic
backends per joint model and perturbation of the papers, gravity, stability, errors and determinism."""
from __future__ import annotations

import ast
import dataclasses
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from jointbench.core.errors import ConfigError
from jointbench.sims import Experiment, simulate
from tests.test_sims import SPEC as SERVO_SPEC   # Westwick & Perreault's experiment (Sec. IV)

mujoco = pytest.importorskip("mujoco")
REPO = Path(__file__).resolve().parents[1]

XU = {   # Xu & Hollerbach's elbow (eq. 7, Fig. 2), as the xu1998 study configures it
    "joint": {"model": "time_varying", "I": 0.06,
              "K": {"shape": "sine", "mean": 40, "amplitude": 15, "frequency": "0.5 Hz"}, "damping_ratio": 0.3},
    "apparatus": {"kind": "torque_drive"},
    "perturbation": {"kind": "prbs", "amplitude": 4, "clock": "10 ms", "sequence": "mls"},
    "sensors": {"angle": {"filter": {"kind": "bessel", "order": 8, "cutoff": "150 Hz", "delay_correction": True}},
                "torque": {"filter": {"kind": "bessel", "order": 8, "cutoff": "150 Hz", "delay_correction": True}}},
    "fs_sim": "2 kHz", "duration": "49 s",
    "acquisition": {"detrend": False, "fs": "1 kHz", "trim": "0.5 s"},
}
WRIST = {   # van de Ruit et al.'s wrist (eqs. 11-13, Table I)
    "joint": {"model": "wrist_contact", "I": "3 g.m2", "b": 0.035,
              "k": {"shape": "square", "mean": 5.6, "amplitude": 0.9, "period": "10 s"}, "b_c": 10, "k_c": 100},
    "apparatus": {"kind": "handle"},
    "perturbation": {"kind": "multisine", "period": "10 s", "f_min": "0.1 Hz", "f_max": "19.3 Hz",
                     "spacing": "0.8 Hz", "corner": "6 Hz", "slope": -20, "rms": "0.02 rad", "quiet": "5 s"},
    "fs_sim": "2500 Hz", "duration": "50 s",
    "acquisition": {"detrend": False, "fs": "44 Hz", "decimation": "fft", "trim": "5 s"},
}


def vaf(x, y) -> float:
    x, y = np.asarray(x), np.asarray(y)
    return 100.0 * (1.0 - np.var(x - y) / np.var(x))


def full_mass(m, d) -> np.ndarray:
    """The dense mass matrix (mj_fullM takes (m, d, dst) since MuJoCo 4, (m, dst, qM) before)."""
    M = np.zeros((m.nv, m.nv))
    try:
        mujoco.mj_fullM(m, d, M)
    except TypeError:
        mujoco.mj_fullM(m, M, d.qM)
    return M


def both(spec: dict, seed: int = 0):
    e = Experiment.from_mapping(spec)
    return simulate(e, seed), simulate(dataclasses.replace(e, backend="mujoco"), seed)


# ------------------------------------------------------------------------------ the library choice
def test_import_sims_loads_no_physics_engine():
    code = ("import sys, jointbench.sims as sims, jointbench.benchmarks.runner, jointbench.cli.studies; "
            "assert 'mujoco' in sims.BACKENDS; "
            "print(sorted(m for m in ('mujoco', 'dm_control') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], cwd=REPO, capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"


def test_models_are_built_with_mjcf_and_compiled_by_mujoco():
    """The choice (sims/backend_mujoco.py): dm_control.mjcf writes the XML, mujoco compiles it; nothing
    uses dm_control's Physics, which breaks whenever MuJoCo renames a model field."""
    from jointbench.sims.backend_mujoco import compiled

    for spec in (SERVO_SPEC, XU, WRIST):
        e = Experiment.from_mapping(spec)
        model, xml = compiled(e)
        assert isinstance(model, mujoco.MjModel) and xml.startswith("<mujoco")
    for f in sorted((REPO / "sims").glob("*.py")):
        names = {n.attr for n in ast.walk(ast.parse(f.read_text())) if isinstance(n, ast.Attribute)}
        assert "Physics" not in names and "from_mjcf_model" not in names, f
        assert "<mujoco" not in f.read_text().replace('xml.startswith("<mujoco")', ""), f"hand-written XML in {f}"


def test_mujoco_version_supports_what_the_backend_uses():
    major, minor = (int(v) for v in mujoco.__version__.split(".")[:2])
    assert (major, minor) >= (3, 17)
    from mujoco import rollout

    assert callable(rollout.rollout) and hasattr(mujoco, "mjd_transitionFD")


# ------------------------------------------------------------------------ the models match their config
def test_servo_and_limb_parameters_come_from_the_config():
    from jointbench.sims.backend_mujoco import compiled

    e = Experiment.from_mapping(SERVO_SPEC)
    m, _ = compiled(e)
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    M = full_mass(m, d)
    assert M[0, 0] == pytest.approx(0.171, rel=1e-12)           # I about the hinge
    drive = m.actuator("drive")
    assert drive.biasprm[1] == pytest.approx(-30000.0) and drive.biasprm[2] == 0.0   # K_a, B_a
    assert m.opt.timestep == pytest.approx(1 / 5000) and m.opt.gravity.tolist() == [0, 0, 0]
    assert m.opt.integrator == mujoco.mjtIntegrator.mjINT_IMPLICITFAST


def test_wrist_contact_is_a_tendon_with_the_contact_parameters():
    from jointbench.sims.backend_mujoco import compiled

    e = Experiment.from_mapping(WRIST)
    m, _ = compiled(e)
    i = m.tendon("contact").id
    assert m.tendon_stiffness[i] == pytest.approx(100.0) and m.tendon_damping[i] == pytest.approx(10.0)
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    M = full_mass(m, d)
    # hand (theta) and handle (delta = u - theta) in one tree: the hand's inertia is the config's 3 g.m2
    assert M[0, 0] - M[1, 1] == pytest.approx(0.003, rel=1e-9)


# ------------------------------------------------------- agreement with the analytic backends (>= 99.9 %)
def test_agreement_torque_driven_elbow_xu():
    """Torque-driven (Xu, eq. 7): the angles agree; the measured torque is the PRBS itself."""
    a, m = both(XU)
    assert vaf(a.angle, m.angle) >= 99.9
    np.testing.assert_allclose(m.torque, a.torque, atol=1e-9)


def test_agreement_torque_driven_elbow_movement():
    """With the voluntary movement theta_n = 0.5 sin(2 pi 0.25 t) (Fig. 3's condition), from a moving start:
    the perturbed part of the angle agrees."""
    spec = dict(XU, voluntary={"movement_amplitude": 0.5, "movement_frequency": "0.25 Hz"})
    a, m = both(spec)
    move = a.truth.signals["movement"]
    assert vaf(a.angle - move, m.angle - move) >= 99.9


def test_agreement_calibration_arm_with_switched_damping():
    spec = dict(XU, joint={"model": "time_varying", "I": 0.0687, "K": 15.4,
                           "B": {"shape": "piecewise", "times": [0, 16.5, 32.5], "values": [1.13, 10.1, 1.13]}})
    a, m = both(spec)
    assert vaf(a.angle, m.angle) >= 99.9


def test_agreement_position_servo_westwick():
    """Position-driven (Westwick, Fig. 1, K_a = 30 000): the torques agree, with voluntary torque and the
    paper's sensors; the angles too."""
    a, m = both(SERVO_SPEC)
    assert vaf(a.torque, m.torque) >= 99.9
    assert vaf(a.angle, m.angle) >= 99.9


def test_agreement_ankle_on_a_compliant_servo():
    spec = dict(SERVO_SPEC, joint={"model": "second_order", "I": 0.01, "B": 0.8, "K": 140},
                apparatus={"kind": "position_servo", "stiffness": 1400}, duration="10 s")
    a, m = both(spec)
    assert vaf(a.torque, m.torque) >= 99.9


@pytest.mark.parametrize("k", [{"shape": "square", "mean": 5.6, "amplitude": 0.9, "period": "10 s"},
                               {"shape": "sine", "mean": 5.6, "amplitude": 0.9, "period": "20 s"}])
def test_agreement_wrist_with_handle(k):
    """Position-driven through the contact (van de Ruit, eqs. 11-13): the torques agree; the handle's own
    servo makes the measured handle angle follow the drive."""
    a, m = both(dict(WRIST, joint={**WRIST["joint"], "k": k}))
    assert vaf(a.torque, m.torque) >= 99.9
    assert vaf(a.angle, m.angle) >= 99.99


def test_damped_servo_agrees_in_the_identification_band():
    """A servo damping (not in the papers): the measured torque agrees below 20 Hz, where the impedance is
    identified (the servo mode at 67 Hz carries the rest, integrated to first order in the damping)."""
    from scipy import signal as sps

    spec = dict(SERVO_SPEC, apparatus={"kind": "position_servo", "stiffness": 30000, "damping": 50},
                duration="10 s")
    a, m = both(spec)
    sos = sps.butter(4, 20, fs=a.fs, output="sos")
    lo_a, lo_m = sps.sosfiltfilt(sos, a.torque), sps.sosfiltfilt(sos, m.torque)
    assert vaf(lo_a, lo_m) >= 99.9
    assert vaf(a.torque, m.torque) >= 99.5


def test_same_seed_same_numbers():
    e = dataclasses.replace(Experiment.from_mapping(dict(WRIST, duration="20 s", perturbation={
        **WRIST["perturbation"], "quiet": "2 s"})), backend="mujoco")
    t1, t2 = simulate(e, 3), simulate(e, 3)
    np.testing.assert_array_equal(t1.angle, t2.angle)
    np.testing.assert_array_equal(t1.torque, t2.torque)


# -------------------------------------------------------------------------------------------- gravity
def gravity_experiment(posture_deg: float, backend: str = "mujoco") -> Experiment:
    spec = dict(XU, duration="10 s", gravity={"mass": "1.65 kg", "com_distance": "0.17 m",
                                              "posture": f"{posture_deg} deg"})
    return Experiment.from_mapping(spec, backend=backend)


@pytest.mark.parametrize("posture", [0.0, 60.0, 90.0, 150.0])
def test_gravity_torque_is_m_g_l_sin_and_the_posture_is_held(posture):
    """The engine's gravity on the forearm equals -m g l sin(posture + theta) along the trajectory (the
    backend's truth signal is computed independently of the engine), and the subject's compensation
    keeps the operating point at theta = 0."""
    from jointbench.sims.backend_mujoco import MujocoBackend

    e = gravity_experiment(posture)
    n = e.n_sim
    zero = np.zeros(n)
    hold = -e.gravity.torque(zero)                     # the voluntary torque that holds theta = 0
    resp = MujocoBackend().respond(e, zero, hold)
    assert np.max(np.abs(resp.angle)) < 1e-9
    # release the arm from theta = 0.1 rad without holding torque: the engine's acceleration at the start
    resp = MujocoBackend().respond(e, zero, zero, x0=(0.1, 0.0))
    g = e.gravity
    I, B, K = (float(v[0]) for v in e.joint.coefficients_at(np.zeros(1)))
    expected = (g.torque(0.1) - K * 0.1) / (I + B / e.fs_sim)    # the damping B acts implicitly
    assert resp.acceleration[0] == pytest.approx(expected, rel=1e-6)
    np.testing.assert_allclose(resp.extra["gravity_stiffness"], g.stiffness(resp.angle))


def test_gravity_is_refused_by_the_analytic_backends():
    with pytest.raises(ConfigError, match=r"^where: backend 'analytic' cannot simulate this experiment: gravity"):
        Experiment.from_mapping(dict(XU, gravity={"mass": 1.65, "com_distance": 0.17}), "where")


def test_gravity_needs_an_inertia_that_holds_the_mass():
    with pytest.raises(ConfigError, match="inertia 0.06 kg.m2 is not above m l\\^2"):
        Experiment.from_mapping(dict(XU, gravity={"mass": "3 kg", "com_distance": "0.3 m"}), backend="mujoco")


def test_handle_dynamics_are_refused_by_the_analytic_backends_and_used_by_mujoco():
    handle = {"kind": "handle", "inertia": "0.02 kg.m2", "servo_stiffness": 200, "servo_damping": 4}
    with pytest.raises(ConfigError, match="the analytic handle is ideal"):
        Experiment.from_mapping(dict(WRIST, apparatus=handle))
    short = dict(WRIST, duration="20 s", perturbation={**WRIST["perturbation"], "quiet": "2 s"})
    soft = simulate(Experiment.from_mapping(dict(short, apparatus=handle), backend="mujoco"), 0)
    stiff = simulate(Experiment.from_mapping(short, backend="mujoco"), 0)     # the ideal handle's stand-in
    # the soft servo yields to the contact torque: the measured handle angle leaves the command
    lag = [np.std(t.angle - t.truth.signals["command"]) for t in (soft, stiff)]
    assert lag[0] > 10 * lag[1]
    assert soft.truth.signals["torque"].std() > 0.5 * stiff.truth.signals["torque"].std()
    with pytest.raises(ConfigError, match="needs all of 'inertia'"):
        Experiment.from_mapping(dict(WRIST, apparatus={"kind": "handle", "inertia": 0.02}), backend="mujoco")


# --------------------------------------------------------------------------- stability and bad input
def test_unstable_step_is_refused_before_the_run_with_the_largest_stable_step():
    """Stiffness is explicit: K_a h^2 / I < 4 for the undamped servo. At 5 kHz, K_a = 3e7 N·m/rad on
    I = 0.171 needs h < 2 sqrt(I / K_a) = 151 us."""
    spec = dict(SERVO_SPEC, apparatus={"kind": "position_servo", "stiffness": 3e7})
    with pytest.raises(ConfigError) as exc:
        Experiment.from_mapping(spec, "study.yaml: parts.fig6: experiment", backend="mujoco")
    msg = str(exc.value)
    assert msg.startswith("study.yaml: parts.fig6: experiment: backend 'mujoco': the step 1/fs_sim = 0.0002 s "
                          "is unstable") and "\n" not in msg
    h = float(msg.split("largest stable step is ")[1].split(" s")[0])
    assert h == pytest.approx(2 * math.sqrt(0.171 / 3e7), rel=2e-3)
    Experiment.from_mapping(dict(spec, fs_sim="7 kHz", acquisition=None), backend="mujoco")    # 143 us: stable
    with pytest.raises(ConfigError, match="unstable"):
        Experiment.from_mapping(dict(spec, fs_sim="6.5 kHz", acquisition=None), backend="mujoco")   # 154 us


def test_divergence_during_the_run_fails_loudly_never_zeros():
    """If an unstable model reaches the engine anyway, MuJoCo resets it to zero with only a warning: the
    backend reads data.warning after the trial and raises, naming the largest stable step."""
    from jointbench.sims.backend_mujoco import MujocoBackend, SimulationDiverged

    e = Experiment.from_mapping(SERVO_SPEC, "where", backend="mujoco")
    bad = object.__new__(Experiment)       # skip validation: the check would refuse it
    for f in dataclasses.fields(Experiment):
        object.__setattr__(bad, f.name, getattr(e, f.name))
    object.__setattr__(bad, "apparatus", dataclasses.replace(e.apparatus, stiffness=1e8))
    n = e.n_sim
    with pytest.raises(SimulationDiverged, match=r"diverged at t = .* s \(BADQACC\); the largest stable step is "
                                                 r"8\.27\de-05 s"):
        MujocoBackend().respond(bad, np.full(n, 0.01), np.zeros(n))


def test_a_model_the_backend_cannot_build_is_one_line():
    @dataclasses.dataclass(frozen=True)
    class GrowingArm:       # an inertia that changes: not a MuJoCo body
        model = "growing_arm"
        contact = None
        time_invariant = False

        def coefficients_at(self, t):
            t = np.asarray(t, float)
            return 0.1 + 0.01 * t, np.full(t.shape, 1.0), np.full(t.shape, 50.0)

    base = Experiment.from_mapping(XU)
    with pytest.raises(ConfigError, match=r"^here: backend 'mujoco' needs a constant inertia, joint model "
                                          r"'growing_arm' varies it$"):
        Experiment(joint=GrowingArm(), perturbation=base.perturbation, fs_sim=base.fs_sim, duration=10.0,
                   apparatus=base.apparatus, backend="mujoco", where="here")
