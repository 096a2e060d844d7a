"""The parallel cascade (one trial and its time-varying ensemble version) and the parameter-varying IRF
on simulated joints with a known reflex and a known K(theta) (estimators/parallel_cascade.py,
estimators/parallel_cascade_tv.py, estimators/pv_irf.py)."""
from __future__ import annotations

import functools

import numpy as np
import pytest

from jointbench import estimators, sims
from jointbench.core.ensemble import Ensemble
from jointbench.core.errors import InputError
from jointbench.core.types import Trial

PRALDS = {"kind": "pralds", "rms": 0.02, "min_hold": "20 ms", "max_hold": "200 ms", "smoothing": "20 Hz"}
ACQ = {"detrend": True, "fs": "100 Hz", "trim": "1 s"}
K_POLY = (100.0, 150.0, 200.0)             # K(theta) = 100 + 150 theta + 200 theta^2 (N.m/rad, theta in rad)
GRID = np.linspace(-0.35, 0.15, 11)        # inside the visited range of the slow movement (-0.41 ... 0.20 rad)


def vaf(y, yhat):
    return 100.0 * (1.0 - np.var(y - yhat) / np.var(y))


@functools.lru_cache(maxsize=None)
def ankle(gain: float, seed: int = 0, duration: float = 60.0, noise: float = 0.03, joint: str = "constant"):
    """The ankle (I 0.015, B 0.8, K 120) on a 30 000 N.m/rad servo (damping 30 N.m.s/rad: zeta 0.7, a stiff
    actuator that does not ring) with a PRALDS, reflex delay 40 ms, 100 Hz."""
    K = 120 if joint == "constant" else {"shape": "sine", "mean": 120, "amplitude": 40, "period": 10}
    g = gain if joint == "constant" else {"shape": "sine", "mean": gain, "amplitude": 0.8 * gain, "period": 10}
    j = {"model": "time_varying", "I": 0.015, "B": 0.8, "K": K, "reflex": {"gain": g, "delay": "40 ms"}}
    e = sims.Experiment.from_mapping({"joint": j, "apparatus": {"kind": "position_servo", "stiffness": 30000,
                                                                "damping": 30},
                                      "perturbation": PRALDS, "sensors": {"torque": {"noise_variance_ratio": noise}},
                                      "fs_sim": 1000, "duration": duration, "acquisition": ACQ}, "test")
    return e


def trial(gain, seed=0, **kw):
    return sims.simulate(ankle(gain, **kw), seed)


# --------------------------------------------------------------------------------------- parallel cascade
def test_without_reflex_the_intrinsic_irf_is_the_two_sided_irf():
    """Acceptance: reflex gain 0 -> the parallel cascade's intrinsic IRF equals the two-sided IRF (irf2_ls with
    the same lags), the reflex pathway is not kept (MDL) and its VAF is 0."""
    tr = trial(0.0)
    pc = estimators.make("parallel_cascade").fit(tr)
    irf = estimators.make("irf2_ls", {"lag_before": 0.04, "lag_after": 0.04}).fit(tr)
    assert pc.reflex_h is None and pc.vaf_reflex == 0.0 and "not kept" in pc.fit_info["reflex"]
    assert np.array_equal(pc.lags, irf.lags) and np.allclose(pc.h, irf.h, rtol=0, atol=1e-12)
    assert pc.intervals.bounds["stiffness"] == pytest.approx(irf.intervals.bounds["stiffness"])
    forced = estimators.make("parallel_cascade", {"keep_reflex": "always"}).fit(tr)   # a reflex fitted to noise
    assert abs(forced.vaf_reflex) < 0.5 and abs(forced.stiffness(0.0) / irf.stiffness(0.0) - 1) < 0.01


@pytest.mark.parametrize("nonlinearity", ["rectifier", "polynomial"])
def test_known_reflex_delay_and_vaf_are_recovered(nonlinearity):
    """Acceptance: a simulated ankle with a 40 ms reflex (4 samples at 100 Hz): the delay within one sample
    (the MDL's first lag that matters: with a second-order activation, which starts from zero, one sample
    after the transport delay),
    the reflex VAF within 2 percentage points of the true reflex torque's VAF of the measured torque (the
    tolerance: the torque noise's 3 % of the variance and the slow onset of the activation low-pass, which
    makes the first reflex lag small), the intrinsic stiffness within 2 % where the two-sided IRF alone
    reads the reflex as stiffness (+14 %)."""
    tr = trial(5.0)
    pc = estimators.make("parallel_cascade", {"nonlinearity": nonlinearity}).fit(tr)
    s = tr.truth.signals
    rows = slice(*pc.rows)
    y = tr.torque - tr.torque.mean()
    true_share = vaf(y[rows], (s["reflex_torque"] - s["reflex_torque"][rows].mean())[rows])
    assert 15 < true_share < 30
    assert abs(pc.reflex_delay - 4) <= 1
    assert abs(pc.vaf_reflex - true_share) <= 2.0
    u = tr.angle - tr.angle.mean()
    sep = vaf((s["reflex_torque"] - s["reflex_torque"][rows].mean())[rows], pc.reflex_torque(u)[rows])
    assert sep > 95.0                                                # the reflex torque itself, separated
    assert abs(pc.stiffness(0.0) - 120.0) < 2.4
    irf = estimators.make("irf2_ls", {"lag_before": 0.04, "lag_after": 0.04}).fit(tr)
    assert irf.stiffness(0.0) - 120.0 > 10.0
    assert np.isclose(pc.predict(u), pc.intrinsic_torque(u) + pc.reflex_torque(u)).all()
    frame = pc.response_frame()
    assert set(frame["pathway"]) == {"intrinsic", "reflex"}
    assert frame.query("pathway == 'reflex'")["lag"].min() == pc.reflex_delay
    if nonlinearity == "polynomial":   # the estimated nonlinearity is rectifier-like: stretch passes, shortening not
        v = np.linspace(0, 0.8, 9)
        nl = pc.nonlinearity
        assert np.ptp(nl(v)) > 4 * np.ptp(nl(-v))


def test_prediction_and_summary():
    tr = trial(5.0)
    pc = estimators.make("parallel_cascade").fit(tr)
    p = pc.prediction(tr)
    assert p.used.sum() == pc.rows[1] - pc.rows[0] and abs(p.vaf() - pc.vaf_total) < 1e-9
    s = pc.summary()
    assert {"vaf_total", "vaf_intrinsic", "vaf_reflex", "reflex_delay"} <= set(s)


@pytest.mark.parametrize("settings, match", [
    ({"delay": 0.6},
     "the reflex delay \\(600 ms\\) is not shorter than the reflex lag window \\(reflex_window = 500 ms"),
    ({"delay_max": 0.5}, "not shorter than the reflex lag window"),
    ({"delay_min": 0.08, "delay_max": 0.05}, "delay_min = 0.08 s is above delay_max"),
])
def test_bad_delay_is_one_line(settings, match):
    with pytest.raises(InputError, match=match) as info:
        estimators.make("parallel_cascade", settings).fit(trial(5.0))
    assert "\n" not in str(info.value)


def test_too_short_a_record_is_one_line():
    tr = trial(5.0)
    short = Trial.from_arrays(tr.angle[:120], tr.torque[:120], tr.fs)
    with pytest.raises(InputError, match="past the lags for .* unknowns"):
        estimators.make("parallel_cascade").fit(short)


# ------------------------------------------------------------------------------ time-varying parallel cascade
def test_tv_cascade_separates_a_time_varying_reflex():
    """An ensemble of 5 with K(t) = 120 +- 40 and a reflex gain 5 +- 4 (sine, 10 s): the TV cascade's
    K(t) stays within 2 % of the intrinsic K (mean bias) where Guarin's TV-IRF without a reflex pathway reads
    +10 % and its linear shortcut still +3 %; the reflex gain is tracked (correlation > 0.98) and the delay
    within two samples (20 s realizations whose stiffness and reflex gain both vary: the single-trial
    cascade reads 6-7 samples on each of them too)."""
    e = ankle(5.0, duration=22.0, joint="varying")
    ens = Ensemble(tuple(sims.simulate(e, 0, realization=r) for r in range(5)))
    t = ens.time
    K = np.asarray(ens.realizations[0].truth.K)
    out = {}
    for name, settings in (("tv_parallel_cascade", {}), ("guarin", {"n_basis": 11}),
                           ("guarin", {"n_basis": 11, "reflex": True})):
        fit = estimators.make(name, settings).fit(ens)
        m = fit.valid & (t > 2) & (t < t[-1] - 2)
        out[name, bool(settings.get("reflex"))] = float(np.mean(fit.stiffness(t)[m] - K[m]) / 120.0)
        if name == "tv_parallel_cascade":
            tv = fit
            g_true = ens.realizations[0].truth.signals["reflex_gain"]
            assert np.corrcoef(fit.reflex_gain[m], g_true[m])[0, 1] > 0.98
            assert abs(fit.reflex_delay - 4) <= 2 and vaf(K[m], fit.stiffness(t)[m]) > 98.0
    assert abs(out["tv_parallel_cascade", False]) < 0.02
    assert out["guarin", False] > 0.10 and out["guarin", True] > 0.03
    u = ens.realizations[0].angle - ens.realizations[0].angle.mean()
    assert np.allclose(tv.predict(u), tv.intrinsic_torque(u) + tv.reflex_torque(u))


# ------------------------------------------------------------------------------------------ pv_irf
@functools.lru_cache(maxsize=None)
def lpv_experiment(noise: float = 0.0, duration: float = 100.0, amplitude: float = 0.305):
    j = {"model": "position_dependent", "I": 0.015, "B": 0.8, "K": {"polynomial": list(K_POLY)},
         "angle_range": [-0.6, 0.4]}
    pert = {"kind": "moving", "movement": {"shape": "sine", "mean": -0.105, "amplitude": amplitude, "frequency": 0.1},
            "perturbation": PRALDS}
    m = {"joint": j, "apparatus": {"kind": "position_servo", "stiffness": 30000}, "perturbation": pert,
         "fs_sim": 1000, "duration": duration, "acquisition": {"detrend": False, "fs": "100 Hz", "trim": "1 s"}}
    if noise:
        m["sensors"] = {"torque": {"noise_rms": noise}}
    return sims.Experiment.from_mapping(m, "test")


def k_true(theta):
    return K_POLY[0] + K_POLY[1] * theta + K_POLY[2] * theta ** 2


def test_pv_irf_recovers_a_quadratic_k_within_its_band_without_noise():
    """Acceptance: on a noise-free trial every point of K(theta) on the grid lies in the 95 % band (the
    band is then the fit's own model error: a few tenths of a N.m/rad)."""
    tr = sims.simulate(lpv_experiment(), 0)
    pv = estimators.make("pv_irf", {"n_basis": 3}).fit(tr)
    lo, hi = pv.stiffness_band(GRID)
    assert np.all((k_true(GRID) >= lo) & (k_true(GRID) <= hi))
    assert np.max(np.abs(pv.stiffness_at(GRID) - k_true(GRID))) < 0.5
    assert pv.lo < -0.38 and pv.hi > 0.18                 # the movement's range, -0.41 ... 0.20 rad
    frame = pv.response_frame()
    assert list(frame.columns) == ["schedule", "stiffness", "stiffness_lo", "stiffness_hi"]
    assert {"stiffness_lo", "stiffness_hi", "schedule"} <= set(pv.to_frame().columns)
    assert pv.prediction(tr).vaf() > 99.0


def test_pv_irf_band_covers_k_at_the_stated_rate():
    """Acceptance: with 0.1 N.m rms torque noise, over 12 seeds the nominal 95 % pointwise band covers the
    true K(theta) at >= 85 % of the seeds x grid points (measured 91-96 % over 20 seeds: the band's t
    quantile and the segment-robust covariance; 85 % leaves room for the spread of a 12-seed estimate)."""
    e = lpv_experiment(noise=0.1, duration=60.0)
    hits = []
    for seed in range(12):
        pv = estimators.make("pv_irf", {"n_basis": 3}).fit(sims.simulate(e, seed))
        lo, hi = pv.stiffness_band(GRID)
        hits.append((k_true(GRID) >= lo) & (k_true(GRID) <= hi))
    assert np.mean(hits) >= 0.85


def test_pv_irf_on_a_recorded_channel():
    """The scheduling variable may be any recorded channel: the true slow movement as a channel gives K(theta)
    as the slow angle does."""
    tr = sims.simulate(lpv_experiment(), 0)
    chan = tr.replace(channels={"position": tr.truth.signals["scheduling"]})
    pv = estimators.make("pv_irf", {"n_basis": 3, "schedule": "position"}).fit(chan)
    assert np.max(np.abs(pv.stiffness_at(GRID) - k_true(GRID))) < 3.0


def test_a_schedule_that_does_not_move_is_one_line():
    tr = sims.simulate(lpv_experiment(), 0)
    rng = np.random.default_rng(0)
    level = 10.0 + 0.01 * rng.uniform(-1, 1, tr.n)           # spans 0.02 of 10: 0.2 %
    with pytest.raises(InputError) as info:
        estimators.make("pv_irf", {"schedule": "emg"}).fit(tr.replace(channels={"emg": level}))
    assert str(info.value) == ("pv_irf: the scheduling variable spans 0.2 % of its range; a parameter-varying fit "
                               "needs movement (channel 'emg' of record 'trial')")
    with pytest.raises(InputError, match="has no channel 'force' to schedule on; known: angle_slow, angle"):
        estimators.make("pv_irf", {"schedule": "force"}).fit(tr)


def test_a_basis_larger_than_the_data_supports_is_one_line():
    tr = sims.simulate(lpv_experiment(duration=12.0), 0)
    with pytest.raises(InputError, match="is larger than .* samples support .*lower n_basis") as info:
        estimators.make("pv_irf", {"n_basis": 20}).fit(tr)
    assert "\n" not in str(info.value)
    steps = np.repeat([-0.2, 0.1], tr.n // 2 + 1)[:tr.n]      # a schedule with two values only
    with pytest.raises(InputError, match="visits too few distinct values for 4 basis polynomials"):
        estimators.make("pv_irf", {"schedule": "level"}).fit(tr.replace(channels={"level": steps}))
