"""Smoke runs of the reflex and lpv studies (benchmarks/studies/reflex/, lpv/): one small case of each part
through the whole harness, its report with the tables and figures (`make reflex` and `make lpv` run them in full)."""
from __future__ import annotations

import pandas as pd
import pytest

from jointbench.benchmarks.config import load_study
from jointbench.benchmarks.study import run_study

REFLEX_SMALL = ["ankle.sweep.gain=[0,10]", "ankle.sweep.variation=[sine]", "ankle.experiment.duration=30 s",
                "ankle.params.realizations=2", "ankle.params.ensemble_size=2", "ankle.params.discard=3 s",
                "ankle.experiment.fs_sim=1 kHz"]
LPV_SMALL = ["kmap.sweep.movement_frequency=[0.1]", "kmap.sweep.range_scale=[1.0]", "kmap.seeds=1",
             "kmap.experiment.duration=60 s"]


def test_the_studies_load_and_expand():
    for sid, n in (("reflex", 16), ("lpv", 36)):
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
    m = cases.set_index(["estimator", "metric"])["value"]
    assert {"kmap_rmse_pct", "kmap_max_error", "band_coverage", "band_halfwidth"} <= set(cases["metric"])
    assert m["pv_irf", "kmap_rmse_pct"] < 5 and m["fsewls", "kmap_rmse_pct"] < 50
    report = (folder / "report.md").read_text()
    assert "K(theta) errors by movement" in report and (folder / "lpv_kmap.png").is_file()


@pytest.mark.parametrize("sid", ["reflex", "lpv"])
def test_the_studies_are_in_the_nightly(sid):
    from jointbench.benchmarks.nightly import load_config

    assert sid in load_config().studies
