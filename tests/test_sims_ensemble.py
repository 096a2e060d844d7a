"""Simulation of ensembles: the realization index, the PRALDS perturbation, simulated subjects (Table II)."""
import dataclasses

import numpy as np
import pytest

from jointbench.core.errors import ConfigError
from jointbench.core.schema import parse
from jointbench.sims import Experiment, simulate
from jointbench.sims.perturbation_pralds import PRALDS
from jointbench.sims.subjects import (SubjectDesign, draw_subjects, draw_trials, simulate_trial, stiffness,
                                      torque_fraction)

WRIST = {
    "joint": {"model": "wrist_contact", "I": "3 g.m2", "b": 0.035, "b_c": 10, "k_c": 100,
              "k": {"shape": "sine", "mean": 5.6, "amplitude": 0.9, "period": "20 s"}},
    "apparatus": {"kind": "handle"},
    "perturbation": {"kind": "pralds", "rms": "0.02 rad", "quiet": "1 s"},
    "sensors": {"torque": {"noise_variance_ratio": 0.1, "noise_filter": {"kind": "butter", "order": 2, "cutoff": 15}}},
    "fs_sim": "1 kHz", "duration": "12 s",
    "acquisition": {"detrend": False, "fs": "100 Hz", "decimation": "fft", "trim": "1 s"},
}


def experiment(**changes) -> Experiment:
    return Experiment.from_mapping({**WRIST, **changes}, "test")


# -------------------------------------------------------------------------------- realization index
def test_realization_redraws_every_stream_and_keeps_the_joint():
    e = experiment()
    a, b, a2 = simulate(e, 7), simulate(e, 7, realization=1), simulate(e, 7, realization=0)
    assert np.array_equal(a.angle, a2.angle) and np.array_equal(a.torque, a2.torque)
    assert not np.allclose(a.angle, b.angle)                         # a new perturbation ...
    assert np.array_equal(a.truth.K, b.truth.K)                      # ... the same time-varying joint
    c = simulate(e, 7, realization=1, replicate=1)                   # replicate on top: new noise only
    assert np.array_equal(b.angle, c.angle) and not np.allclose(b.torque, c.torque)
    assert not np.array_equal(simulate(e, 7, realization=2).angle, b.angle)
    r1 = simulate(e, 7, replicate=1)                                 # a replicate keeps the perturbation
    assert np.array_equal(a.angle, r1.angle)
    with pytest.raises(ValueError, match="realization must be a whole number"):
        simulate(e, 7, realization=-1)


# ------------------------------------------------------------------------------------------ PRALDS
def test_pralds_levels_holds_rms_and_quiet_margins():
    p = PRALDS(rms=0.02, min_hold=0.05, max_hold=0.15, smoothing=None, quiet=1.0)
    fs, n = 1000.0, 20000
    u = p.generate(n, fs, np.random.default_rng(3))
    active = slice(1000, 19000)
    assert np.all(u[:1000] == 0) and np.all(u[19000:] == 0)
    assert np.sqrt(np.mean(u[active] ** 2)) == pytest.approx(0.02, rel=1e-12)
    assert abs(np.mean(u[active])) < 1e-12
    switches = np.flatnonzero(np.diff(u[active]) != 0)
    holds = np.diff(switches) / fs
    assert holds.min() >= 0.05 - 1.5 / fs and holds.max() <= 0.15 + 1.5 / fs
    levels = u[active][switches + 1]
    assert len(np.unique(np.round(levels, 12))) > 0.9 * len(levels)      # arbitrary levels, not binary
    smooth = dataclasses.replace(p, smoothing=20.0).generate(n, fs, np.random.default_rng(3))
    assert np.abs(np.diff(smooth)).max() < 0.2 * np.abs(np.diff(u)).max()  # the handle does not jump
    assert np.sqrt(np.mean(smooth[active] ** 2)) == pytest.approx(0.02, rel=1e-12)


def test_pralds_bad_settings():
    with pytest.raises(ConfigError, match="max_hold"):
        PRALDS(min_hold=0.2, max_hold=0.1)
    with pytest.raises(ConfigError, match="min_hold"):
        experiment(perturbation={"kind": "pralds", "min_hold": "0.1 ms"})
    with pytest.raises(ConfigError, match="fewer than 10"):
        experiment(perturbation={"kind": "pralds", "max_hold": "2 s", "quiet": "2 s"})


# ---------------------------------------------------------------------------------------- subjects
DESIGN = {"count": 3, "trials": 3, "noise_variance_ratio": [0.1, 0.2, 0.4], "timing_sd": "1 s"}


def test_subjects_are_drawn_around_the_model_and_fixed_by_their_seed():
    e = experiment()
    d = parse(SubjectDesign, DESIGN, "test")
    a, b = draw_subjects(d, e.joint), draw_subjects(d, e.joint)
    assert a == b and [s.label for s in a] == ["P1", "P2", "P3"]
    assert [s.noise_variance_ratio for s in a] == [0.1, 0.2, 0.4]
    assert len({s.k_mean for s in a}) == 3 and all(0.3 < s.k_mean / 5.6 < 3 for s in a)
    other = draw_subjects(dataclasses.replace(d, seed=1), e.joint)
    assert other[0].k_mean != a[0].k_mean
    plans, again = draw_trials(d, a[0], 5), draw_trials(d, a[0], 5)
    assert plans == again and len({p.shift for p in plans}) == 3 and draw_trials(d, a[0], 6) != plans


def test_stiffness_follows_the_trials_torque():
    e = experiment()
    d = parse(SubjectDesign, {**DESIGN, "timing_sd": 0, "amplitude_sd": 0, "drift_sd": 0}, "test")
    s = draw_subjects(d, e.joint)[0]
    plan = draw_trials(d, s, 0)[0]
    t = np.linspace(0, 40, 4001)
    frac = torque_fraction(d, plan, t, 40.0)
    assert frac.min() == pytest.approx(0.05, abs=1e-6) and frac.max() == pytest.approx(0.20, abs=1e-6)
    k = stiffness(d, plan, t, 40.0)
    assert k.min() == pytest.approx(s.k_mean - s.k_swing, abs=1e-6)
    assert k.max() == pytest.approx(s.k_mean + s.k_swing, abs=1e-6)
    assert np.corrcoef(k, frac)[0, 1] == pytest.approx(1.0)


@pytest.mark.parametrize("same_input", [True, False])
def test_subject_trials_add_the_voluntary_torque(same_input):
    e = experiment(duration="42 s")
    d = parse(SubjectDesign, DESIGN, "test")
    s = draw_subjects(d, e.joint)[1]
    plans = draw_trials(d, s, 0)
    a, b = (simulate_trial(e, d, p, 0, same_input) for p in plans[:2])
    assert a.name == "P2-T1" and a.fs == 100.0 and a.n == 4000
    assert np.array_equal(a.angle, b.angle) == same_input
    tv = a.truth.signals["voluntary"]
    assert np.allclose(tv, s.mvt * torque_fraction(d, plans[0], e.acquired_times(), 42.0))
    noise = a.torque - tv - a.truth.signals["torque"]
    assert np.var(noise) / np.var(a.truth.signals["torque"]) == pytest.approx(0.2, rel=1e-6)
    assert not np.array_equal(a.truth.K, b.truth.K)          # each trial its own k(t)
    again = simulate_trial(e, d, plans[0], 0, same_input)
    assert np.array_equal(a.torque, again.torque)


def test_subject_design_validation():
    with pytest.raises(ConfigError, match="one per subject"):
        parse(SubjectDesign, {"count": 3, "noise_variance_ratio": [0.1, 0.2]}, "test")
    with pytest.raises(ConfigError, match="torque_low"):
        parse(SubjectDesign, {"torque_low": 0.3, "torque_high": 0.2}, "test")
