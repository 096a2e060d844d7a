"""Smoke runs of the reflex and lpv studies (benchmarks/studies/reflex/, lpv/): one small case of each part
through the whole harness, its report with the tables and figures (`make reflex` and `make lpv` run them in full)."""
from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from jointbench.benchmarks.checks import verdict
from jointbench.benchmarks.compare import stats as cs
from jointbench.benchmarks.compare.tables import ALPHA
from jointbench.benchmarks.config import load_study
from jointbench.benchmarks.study import run_study

REFLEX_SMALL = ["ankle.sweep.gain=[0,10]", "ankle.sweep.variation=[sine]", "ankle.experiment.duration=30 s",
                "ankle.params.realizations=2", "ankle.params.ensemble_size=2", "ankle.params.discard=3 s",
                "ankle.experiment.fs_sim=1 kHz"]
LPV_SMALL = ["kmap.sweep.movement_frequency=[0.1]", "kmap.sweep.range_scale=[1.0]", "kmap.seeds=1",
             "kmap.experiment.duration=60 s", "reflex.sweep.reflex_gain=[10]", "reflex.sweep.fs=[100]",
             "reflex.seeds=1", "reflex.experiment.duration=60 s"]


def test_the_studies_load_and_expand():
    for sid, n in (("reflex", 16), ("lpv", 240 + 72)):          # lpv: kmap, and the reflex part (issue 37)
        study = load_study(sid)
        assert study.checks and all(c.evidence == "sanity" for c in study.checks)
        assert {r.id for r in study.readings}
        from jointbench.benchmarks.runner import expand
        assert len(expand(study)) == n


def test_reflex_study_smoke(tmp_path):
    run = run_study("reflex", parts=["ankle"], out_root=tmp_path, serial=True, progress=False, use_cache=False,
                    overrides=REFLEX_SMALL)
    folder = tmp_path / "reflex"
    cases = pd.read_csv(folder / "cases.csv")
    assert set(cases["status"]) == {"ok"}
    got = set(cases["metric"])
    assert {"bias_mean_pct", "bias_rms", "random_error", "reflex_share", "separation_reflex", "separation_intrinsic",
            "vaf_reflex", "vaf_reflex_true", "delay_error_samples"} <= got
    assert set(cases["estimator"].dropna()) >= {"parallel_cascade", "tv_parallel_cascade", "fsewls", "kbr", "sds",
                                                 "guarin", "ensemble_irf", "irf2_ls"}
    report = (folder / "report.md").read_text()
    assert "stiffness bias (% of the intrinsic K" in report and "the parallel cascades' separation" in report
    assert (folder / "reflex_ankle.png").is_file()
    tv = cases[(cases["estimator"] == "tv_parallel_cascade") & (cases["metric"] == "separation_reflex")]
    assert tv["value"].min() > 90            # the time-varying gain separated (RF3's sanity level)
    assert run is not None


def test_lpv_study_smoke(tmp_path):
    run_study("lpv", out_root=tmp_path, serial=True, progress=False, use_cache=False, overrides=LPV_SMALL)
    folder = tmp_path / "lpv"
    cases = pd.read_csv(folder / "cases.csv")
    assert set(cases["status"]) == {"ok"}
    m = cases[cases["part"] == "kmap"].set_index(["estimator", "metric"])["value"]
    r = cases[cases["part"] == "reflex"].set_index(["estimator", "metric"])["value"]
    assert {"kmap_rmse_pct", "kmap_max_error", "band_coverage", "band_halfwidth"} <= set(cases["metric"])
    assert m["pv_irf", "kmap_rmse_pct"] < 5 and m["fsewls", "kmap_rmse_pct"] < 50
    report = (folder / "report.md").read_text()
    assert "K(theta) errors by movement" in report and (folder / "lpv_kmap.png").is_file()
    assert r["pv_parallel_cascade", "kmap_rmse_pct"] < 5 and r["pv_irf", "kmap_rmse_pct"] > 20      # part reflex
    assert "K(theta) with a reflex" in report
    assert (folder / "lpv_reflex.png").is_file()


@pytest.mark.parametrize("sid", ["reflex", "lpv"])
def test_the_studies_are_in_the_nightly(sid):
    from jointbench.benchmarks.nightly import load_config

    assert sid in load_config().studies


# --- issue 35: the reflexes within the cited range; "better" only from a paired test ---

def _share_rows(part: str, shares: dict) -> pd.DataFrame:
    return pd.DataFrame([{"part": part, "status": "ok", "metric": "reflex_share", "estimator": "", "gain": g,
                          "variation": v, "value": x} for (g, v), x in shares.items()])


def test_reflex_share_checks_judge_the_largest_share_against_the_cited_range():
    checks = {c.id: c for c in load_study("reflex").checks}
    rf0 = checks["RF0-share-ankle"]
    assert (rf0.low, rf0.high, rf0.aggregate, rf0.evidence) == (1.0, 55.0, "max", "sanity")
    inside = _share_rows("ankle", {(0, "constant"): 0.0, (16, "constant"): 43.2, (16, "sine"): 47.7})
    rep, _, n, *_, status = verdict(rf0, inside)
    assert (rep, n, status) == (47.7, 2, "pass")            # gain 0 left out; the largest share judged
    beyond = _share_rows("ankle", {(16, "constant"): 43.2, (16, "sine"): 78.6})   # the 0 ... 2G sine of before
    assert verdict(rf0, beyond)[-1] == "miss"


def test_the_time_varying_gain_peaks_at_the_constant_gain():
    from jointbench import sims
    from jointbench.benchmarks.studies.reflex.protocol import ReflexParams, with_gain

    part = load_study("reflex").parts["ankle"]
    exp = sims.Experiment.from_mapping(part.experiment, "ankle")
    t = np.linspace(0, 50, 5001)
    g = np.asarray(with_gain(exp, ReflexParams(gain=16.0, variation="sine")).reflex.gain_at(t), float)
    assert g.min() == pytest.approx(0.0, abs=1e-6) and g.max() == pytest.approx(16.0, rel=1e-6)
    c = np.asarray(with_gain(exp, ReflexParams(gain=16.0, variation="constant")).reflex.gain_at(t), float)
    assert np.allclose(c, 16.0)


def _power(n: int, family: int, effect: float = 1.0, draws: int = 2000) -> float:
    """Monte-Carlo power of the signed-rank test at Holm's strictest step (alpha / family) against normal
    paired differences whose mean is ``effect`` standard deviations."""
    rng = np.random.default_rng(35)
    return float(np.mean([cs.signed_rank_p(rng.normal(effect, 1.0, n)) < ALPHA / family for _ in range(draws)]))


def test_lpv_seeds_give_the_paired_test_its_power():
    """Reading L6: the config's seeds find, at Holm's strictest step over the movements, a difference of one SD
    of the paired differences at least 80 % of the time; 3 seeds (the study's former number) never can."""
    part = load_study("lpv").parts["kmap"]
    family = len(part.sweep["movement_frequency"]) * len(part.sweep["range_scale"])
    assert _power(len(part.seeds), family) >= 0.8
    assert cs.min_signed_rank_p(3) > ALPHA and _power(3, family) == 0.0


def _kmap_rows(diffs: dict) -> pd.DataFrame:
    """pv_irf and fsewls errors per movement and seed: fsewls 1.0 + noise, pv_irf that plus the movement's shift."""
    rng = np.random.default_rng(0)
    recs = []
    for (f, r), (shift, n) in diffs.items():
        for seed in range(n):
            base = 1.0 + 0.1 * rng.standard_normal()
            for est, v in (("fsewls", base), ("pv_irf", base + shift + 0.05 * rng.standard_normal())):
                recs.append({"movement_frequency": f, "range_scale": r, "seed": seed, "estimator": est,
                             "metric": "kmap_rmse_pct", "value": v, "status": "ok"})
    return pd.DataFrame(recs)


def test_lpv_better_is_said_from_the_paired_test_only():
    from jointbench.benchmarks.studies.lpv.figures import _summary, paired_tests

    rows = _kmap_rows({(0.05, 1.0): (-0.5, 20), (0.1, 1.0): (+0.5, 20), (0.2, 1.0): (0.0, 20)})
    t = paired_tests(rows).set_index("movement_frequency")
    assert list(t["better"]) == ["pv_irf", "fsewls", ""] and (t["n"] == 20).all()
    text = _summary(rows)
    assert "significantly smaller RMS error in 1 of the 3 movements (0.05 Hz x 1)" in text
    assert "FSEWLS mapped through theta in 1 (0.1 Hz x 1)" in text and "no significant difference in 1." in text
    few = _kmap_rows({(0.05, 1.0): (-0.5, 3), (0.1, 1.0): (-0.5, 3)})     # pv_irf ahead in every seed, 3 seeds
    assert "in 0 of the 2 movements" in _summary(few) and (paired_tests(few)["better"] == "").all()
