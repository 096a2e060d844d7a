"""The parameter-varying parallel cascade (estimators/pv_parallel_cascade.py, issue 37) on a simulated ankle whose
stiffness depends on the angle, with a stretch reflex whose gain rises with dorsiflexion: K(theta) within its band
where pv_irf reads the reflex torque as stiffness; the reflex's gain along the schedule; ``jointbench estimate
--schedule`` on a CSV record."""
from __future__ import annotations

import functools
import re

import numpy as np
import pandas as pd
import pytest

from jointbench import estimators, sims
from jointbench.core.errors import ConfigError, InputError
from jointbench.core.scores import vaf
from tests.test_cli_estimate import cli

K_POLY = (100.0, 150.0, 200.0)          # K(theta) = 100 + 150 theta + 200 theta^2 (N.m/rad), the lpv study's (L1)
MEAN, AMPLITUDE = -0.105, 0.305         # the slow movement (rad): -0.41 ... 0.20, at 0.1 Hz
CHANGE = 0.5                            # the reflex gain: (1 +- 0.5) G0 at the movement's ends (the lpv study's L7)
PRALDS = {"kind": "pralds", "rms": 0.02, "min_hold": "20 ms", "max_hold": "200 ms", "smoothing": "20 Hz"}


@functools.lru_cache(maxsize=None)
def experiment(gain: float, fs: float = 200.0, noise: float = 0.2, duration: float = 100.0,
               acquired: bool = True) -> sims.Experiment:
    """The lpv study's reflex part (benchmarks/studies/lpv/study.yaml, readings L1, L2, L7): the ankle with
    K(theta) on a stiff, damped servo, a 0.1 Hz movement over -0.41 ... 0.20 rad with a PRALDS on top, and the
    reflex study's stretch reflex (40 ms, half-wave rectifier, 3.2 Hz activation) with the gain G0 (1 + 0.5
    (theta - mean) / amplitude): a sine in phase with the movement. 0.2 N.m rms torque noise."""
    j = {"model": "position_dependent", "I": 0.01, "B": 0.8, "K": {"polynomial": list(K_POLY)},
         "angle_range": [-0.6, 0.4]}
    if gain:
        g = {"shape": "sine", "mean": gain, "amplitude": gain * CHANGE, "frequency": 0.1}
        j["reflex"] = {"pathway": "stretch", "gain": g, "delay": "40 ms", "frequency": 3.2, "damping_ratio": 0.7}
    pert = {"kind": "moving", "movement": {"shape": "sine", "mean": MEAN, "amplitude": AMPLITUDE, "frequency": 0.1},
            "perturbation": PRALDS, "fade": 1.0}
    acq = {"detrend": False, "trim": "1 s", **({"fs": fs} if acquired else {})}
    return sims.Experiment.from_mapping({"joint": j, "apparatus": {"kind": "position_servo", "stiffness": 30000,
                                                                   "damping": 30},
                                         "perturbation": pert, "sensors": {"torque": {"noise_rms": noise}},
                                         "fs_sim": 1000, "duration": duration, "acquisition": acq}, "test")


@functools.lru_cache(maxsize=None)
def trial(gain: float, seed: int = 0, fs: float = 200.0):
    return sims.simulate(experiment(gain, fs), seed)


def grid(tr) -> np.ndarray:
    """21 points over the central 90 % of the range the true slow movement visits (the lpv study's L5)."""
    return np.linspace(*np.quantile(tr.truth.signals["scheduling"], [0.05, 0.95]), 21)


def k_true(theta):
    return K_POLY[0] + K_POLY[1] * theta + K_POLY[2] * theta ** 2


def gain_true(theta, gain):
    return gain * (1.0 + CHANGE * (theta - MEAN) / AMPLITUDE)


#: both estimators told the movement's frequency: the slow angle below 3 x 0.1 Hz (the lpv study's L3)
SLOW = {"slow_cutoff": 0.3}


def test_band_holds_k_theta_with_a_reflex_where_pv_irf_is_biased():
    """Acceptance (issue 37): on 8 simulated trials (200 Hz, reflex gain 10 N.m.s/rad at the mean angle, +-50 %
    along the movement: a reflex share of about 48 % of the torque the perturbation evokes) the 95 % pointwise
    band of pv_parallel_cascade's K(theta) holds the true K at >= 85 % of the seeds x 21 grid points over the
    central 90 % of the schedule's range (pv_irf's own rule without a reflex, tests/test_reflex_estimators.py;
    measured 90 %), and its mean error stays within 1 % of the mean K (measured -0.1 %, each seed within 0.6 %).
    pv_irf on the same trials reads the reflex torque as stiffness: its K(theta) is above the truth by more than
    20 % of the mean K in every seed (measured 34 % to 47 %) and its band holds the truth at under 10 % of the
    points (measured 0.6 %)."""
    hits, bias, pv_bias, pv_hits = [], [], [], []
    for seed in range(8):
        tr = trial(10.0, seed)
        th = grid(tr)
        k = k_true(th)
        pc = estimators.make("pv_parallel_cascade", SLOW).fit(tr)
        lo, hi = pc.stiffness_band(th)
        hits.append((k >= lo) & (k <= hi))
        bias.append(np.mean(pc.stiffness_at(th) - k) / np.mean(k))
        pv = estimators.make("pv_irf", SLOW).fit(tr)
        plo, phi = pv.stiffness_band(th)
        pv_hits.append((k >= plo) & (k <= phi))
        pv_bias.append(np.mean(pv.stiffness_at(th) - k) / np.mean(k))
    assert np.mean(hits) >= 0.85, np.mean(hits, axis=1)
    assert abs(np.mean(bias)) < 0.01, bias
    assert min(pv_bias) > 0.20 and np.mean(pv_hits) < 0.10, (pv_bias, np.mean(pv_hits))


def test_at_100_hz_the_reflex_is_not_read_as_stiffness():
    """At 100 Hz (the lpv study's kmap rate) K(theta) is within 2.5 % RMS of the truth (measured 1.1 %, a bias of
    -1.0 %: the rectified velocity of a 100 Hz record, the estimator's Notes and the study's reading L8) where pv_irf
    is 42 % off."""
    tr = trial(10.0, 0, fs=100.0)
    th = grid(tr)
    k = k_true(th)
    pc = estimators.make("pv_parallel_cascade", SLOW).fit(tr)
    pv = estimators.make("pv_irf", SLOW).fit(tr)
    assert np.sqrt(np.mean((pc.stiffness_at(th) - k) ** 2)) / np.mean(k) < 0.025
    assert np.sqrt(np.mean((pv.stiffness_at(th) - k) ** 2)) / np.mean(k) > 0.20


def test_the_reflex_pathway_follows_the_schedule():
    """The reflex's static gain along the schedule is within 5 % RMS of the simulated G(theta) (measured 1.2 % to 2.7 %
    over 8 seeds at 200 Hz) and its torque is the simulated reflex torque's (VAF above 99 %, measured 99.96 %); the
    delay, where its Laguerre IRF starts, is not after the transport delay (40 ms) plus one sample (measured 30 to
    45 ms over 8 seeds); the prediction is the sum of both pathways and explains the torque."""
    tr = trial(10.0, 0)
    th = grid(tr)
    pc = estimators.make("pv_parallel_cascade", SLOW).fit(tr)
    assert pc.reflex_h is not None and pc.fit_info["reflex"] == "kept (CV)"
    g = gain_true(th, 10.0)
    assert np.sqrt(np.mean((pc.reflex_gain_at(th) - g) ** 2)) / np.mean(g) < 0.05
    assert 0.02 <= pc.reflex_delay / tr.fs <= 0.045
    used, true = pc.valid, tr.truth.signals["reflex_torque"]
    fitted = pc.reflex_torque(tr.input)
    assert vaf(true[used] - true[used].mean(), fitted[used] - fitted[used].mean()) > 99.0
    u = tr.input
    assert np.allclose(pc.predict(u), pc.intrinsic_torque(u) + pc.reflex_torque(u))
    assert pc.prediction(tr).vaf() > 99.0
    frame = pc.response_frame()
    assert list(frame.columns) == ["schedule", "stiffness", "stiffness_lo", "stiffness_hi", "reflex_gain"]
    summary = pc.summary()
    assert summary["vaf_reflex"] > 0 and "static gain" in summary["reflex"]


def test_without_a_reflex_the_pathway_is_dropped():
    """No reflex: the cross-validation drops the reflex pathway, and K(theta) is within its band at
    >= 90 % of the grid and within 1 % RMS of the truth, as pv_irf's (measured 0.2 % and 0.3 %); a reflex pathway
    forced on it explains nothing (VAF 0.04 %)."""
    tr = trial(0.0, 0, fs=100.0)
    th = grid(tr)
    k = k_true(th)
    pc = estimators.make("pv_parallel_cascade", SLOW).fit(tr)
    assert pc.reflex_h is None and pc.vaf_reflex == 0.0 and "not kept" in pc.fit_info["reflex"]
    assert np.all(np.isnan(pc.reflex_gain_at(th))) and np.allclose(pc.reflex_torque(tr.input), 0.0)
    lo, hi = pc.stiffness_band(th)
    assert np.mean((k >= lo) & (k <= hi)) >= 0.9
    assert np.sqrt(np.mean((pc.stiffness_at(th) - k) ** 2)) / np.mean(k) < 0.01
    forced = estimators.make("pv_parallel_cascade", {**SLOW, "keep_reflex": "always"}).fit(tr)   # fitted to noise
    assert forced.reflex_h is not None and abs(forced.vaf_reflex) < 0.5


@pytest.mark.parametrize("name", ["pv_irf", "pv_parallel_cascade"])
@pytest.mark.parametrize("key, value", [("pseudo_inverse", "off"), ("remove_mean", False)])
def test_the_two_sided_irfs_preprocessing_settings_are_not_taken(name, key, value):
    """The parameter-varying IRFs take the lags of the two-sided IRFs but not their preprocessing (they remove the
    torque's mean and solve with their own pseudo-inverse): a setting that would change nothing is refused."""
    with pytest.raises(ConfigError, match=f"unknown key '{key}'"):
        estimators.make(name, {key: value})


def test_settings_and_refusals_are_one_line():
    with pytest.raises(ConfigError, match="pv_parallel_cascade: slow_cutoff = 2 Hz has no effect with schedule "
                                          "'angle'"):
        estimators.make("pv_parallel_cascade", {"schedule": "angle", "slow_cutoff": 2.0})
    short = sims.simulate(experiment(10.0, 100.0, duration=12.0), 0)
    with pytest.raises(InputError, match="reflex ones .* are more than .* samples support .*lower n_basis") as info:
        estimators.make("pv_parallel_cascade", {"laguerre_order": 16, "reflex_basis": 10}).fit(short)
    assert "\n" not in str(info.value)
    with pytest.raises(InputError, match="not shorter than the reflex lag window"):
        estimators.make("pv_parallel_cascade", {"delay": 0.5, "reflex_window": 0.3}).fit(short)


# ------------------------------------------------------------------------------ jointbench estimate --schedule
@pytest.fixture(scope="module")
def recording(tmp_path_factory):
    """100 s of the ankle with a reflex (gain 10 at the mean angle) at 1 kHz, as a CSV with a further column
    'position' (the slow movement, as a lab records it apart)."""
    tr = sims.simulate(experiment(10.0, duration=102.0, acquired=False), 0)
    path = tmp_path_factory.mktemp("pvpc") / "ankle_reflex.csv"
    pd.DataFrame({"time": tr.time, "angle": tr.angle, "torque": tr.torque,
                  "position": tr.truth.signals["scheduling"]}).to_csv(path, index=False)
    return path


@pytest.mark.parametrize("schedule", ["angle_slow", "position"])
def test_estimate_schedule_on_a_csv_record(recording, tmp_path, capsys, schedule):
    """``jointbench estimate -e pv_parallel_cascade --schedule ...`` on a 1 kHz CSV decimated to 100 Hz: K at the
    chosen values within its interval and within 3 % of the truth (measured under 1.5 %), the reflex reported."""
    args = ["-e", "pv_parallel_cascade", "-i", recording, "-o", tmp_path / "out.csv", "--decimate", "10",
            "--schedule", schedule, "--at=-0.3,0,0.15"] + (["--set", "slow_cutoff=0.3"] if schedule == "angle_slow"
                                                            else [])
    rc = cli(args, capsys)
    out = capsys.readouterr().out
    assert rc == 0, out
    assert f"K at chosen values of the scheduling variable '{schedule}'" in out
    rows = [tuple(map(float, m)) for m in re.findall(r"^\s+(\S+)\s+K = (\S+) \[(\S+), (\S+)\] N\.m/rad", out, re.M)]
    assert [r[0] for r in rows] == [-0.3, 0.0, 0.15]
    for v, k, lo, hi in rows:
        assert lo < k < hi and abs(k / k_true(v) - 1) < 0.03, (v, k, k_true(v))
    assert re.search(r"reflex: delay \d+ ms, \d+ lags; static gain", out)
    gains = [float(g) for g in re.findall(r"N\.m/rad, reflex gain (\S+) N\.m\.s/rad$", out, re.M)]
    assert len(gains) == 3 and gains[0] < gains[1] < gains[2]              # rising with dorsiflexion (L7)
    resp = pd.read_csv(tmp_path / "out_response.csv")
    assert list(resp.columns) == ["schedule", "stiffness", "stiffness_lo", "stiffness_hi", "reflex_gain"]


# ------------------------------------------------------------------------------------- the lpv study's part reflex
def test_the_reflex_part_gives_its_paired_tests_their_power():
    """Reading L9: with the part's seeds the signed-rank test can reach Holm's strictest step over its family (every
    cell x both comparisons); and a 12-seed difference in every seed is called, a mixed one is not."""
    from jointbench.benchmarks.compare import stats as cs
    from jointbench.benchmarks.compare.tables import ALPHA
    from jointbench.benchmarks.config import load_study
    from jointbench.benchmarks.studies.lpv.figures import reflex_tests

    part = load_study("lpv").parts["reflex"]
    family = 2 * len(part.sweep["reflex_gain"]) * len(part.sweep["fs"])
    assert cs.min_signed_rank_p(len(part.seeds)) < ALPHA / family
    rng = np.random.default_rng(0)
    recs = []
    for g0, shift in ((0, 0.0), (10, 40.0)):
        for seed in range(12):
            base = 0.5 + 0.1 * rng.standard_normal()
            for est, v in (("pv_parallel_cascade", base), ("pv_irf", base + shift + (-1) ** seed * 0.2),
                           ("fsewls", base + (-1) ** seed * 0.2)):         # no shift: differences of both signs
                recs.append({"reflex_gain": g0, "fs": 100.0, "seed": seed, "estimator": est,
                             "metric": "kmap_rmse_pct", "value": v, "status": "ok"})
    t = reflex_tests(pd.DataFrame(recs)).set_index(["b", "reflex_gain"])
    assert len(t) == 4 and t.loc[("pv_irf", 10), "better"] == "pv_parallel_cascade"
    assert t.loc[("pv_irf", 0), "better"] == "" and (t.loc["fsewls", "better"] == "").all()
    smallest = t.loc[("pv_irf", 10)]                                   # Holm over all 4 tests: its first step
    assert (t["p_holm"] >= t["p"]).all() and smallest["p_holm"] == pytest.approx(4 * smallest["p"])


def test_cross_validation_drops_a_spurious_reflex_that_mdl_keeps():
    """Issue 33's narrow-band record (no reflex, torque noise low-passed at 30 Hz, 20 ms lags): the minimum
    description length keeps a reflex pathway fitted to the coloured noise in most seeds (19 of 30; 3 of seeds
    0-4), the default cross-validation over left-out segments in none of seeds 0-4 (1 of 30)."""
    from jointbench.testing.data import narrow_band

    lags = {"lag_before": 0.02, "lag_after": 0.02}
    kept = {how: [] for how in ("cv", "mdl")}
    for seed in range(5):
        tr = narrow_band(seed)
        for how in kept:
            est = estimators.make("pv_parallel_cascade", {**lags, "keep_reflex": how}).fit(tr)
            kept[how].append(est.reflex_h is not None)
            assert est.fit_info["reflex"].startswith("kept (CV)" if est.reflex_h is not None and how == "cv" else
                                                     "kept (MDL)" if est.reflex_h is not None else "not kept")
    assert sum(kept["cv"]) == 0 and sum(kept["mdl"]) >= 2, kept
