"""The comparison matrix's study side (issue 18): identifiability figures against a hand-computed case,
intervals that contain their value, the tuning policy (never the scored realizations, never the truth), a
``--set`` run that leaves the study's own results untouched, and Parquet with the scenario's fields as
columns. Tiny grids (tests/harness_studies.py); each test runs in seconds."""
from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

from jointbench import sims
from jointbench.benchmarks.config import load_study
from jointbench.benchmarks.harness.case import run_case
from jointbench.benchmarks.compare.identifiability import identifiability
from jointbench.benchmarks.compare import protocol as compare_mod
from jointbench.benchmarks.compare.protocol import TUNE_OFFSET, recentred_percentile_interval
from jointbench.benchmarks.runner import expand_study
from jointbench.benchmarks.study import run_study
from tests.harness_studies import tiny_grid_part, tiny_study


# ------------------------------------------------------------------------------------ identifiability
def test_identifiability_of_a_sine_stiffness_on_a_constant_angle_by_hand():
    # k(t) = 50 + 10 sin(2 pi t / 1 s) on a constant angle 0.1 rad, over 4 whole periods at 100 Hz; noise
    # +-0.2 N.m alternating (variance 0.04, orthogonal to the sine over whole periods)
    t = np.arange(400) / 100.0
    k = 50 + 10 * np.sin(2 * np.pi * t)
    theta = np.full_like(t, 0.1)
    noise = 0.2 * (-1.0) ** np.arange(len(t))
    clean = k * theta
    got = identifiability(k, theta, clean + noise, clean)
    v_k = 0.1 ** 2 * 10 ** 2 / 2                   # var(k theta) = theta^2 A^2 / 2 = 0.5 (N.m)^2
    v_tau = v_k + 0.04
    assert got["stiffness_share"] == pytest.approx(100 * v_k / v_tau, rel=1e-9)
    assert got["tv_share"] == pytest.approx(100 * v_k / v_tau, rel=1e-9)     # all of k theta varies
    assert got["noise_share"] == pytest.approx(100 * 0.04 / v_tau, rel=1e-9)
    assert got["tv_snr_db"] == pytest.approx(10 * math.log10(0.5 / 0.04), rel=1e-9)   # 10.97 dB


def test_identifiability_of_a_constant_stiffness_has_no_time_varying_part():
    t = np.arange(1000) / 100.0
    theta = 0.02 * np.sin(2 * np.pi * 3 * t)
    got = identifiability(40.0, theta, 40 * theta, 40 * theta, mask=t > 1)
    assert got["stiffness_share"] == pytest.approx(100) and got["tv_share"] == 0
    assert got["tv_snr_db"] == -math.inf and got["noise_share"] == 0
    with pytest.raises(ValueError, match="differ in shape"):
        identifiability(np.ones(3), theta, theta, theta)


# ------------------------------------------------------------------------------------------ intervals
def test_percentile_interval_contains_its_value_even_when_the_bootstrap_is_biased():
    rng = np.random.default_rng(1)
    for shift in (-3.0, 0.0, 2.5, 10.0):          # draws all above (or below) the value: the raw percentiles exclude it
        draws = 5 + shift + rng.standard_normal(200)
        lo, hi = recentred_percentile_interval(5.0, draws, floor=None)
        assert lo <= 5.0 <= hi
        assert hi - lo == pytest.approx(np.percentile(draws, 95, method="higher")
                                        - np.percentile(draws, 5, method="lower"))    # the spread is kept
    assert recentred_percentile_interval(math.inf, [1.0, 2.0]) == (math.inf, math.inf)
    lo, hi = recentred_percentile_interval(1.0, [1.0] * 10 + [math.inf] * 190)
    assert lo <= 1.0 <= hi and hi == math.inf


# ---------------------------------------------------------------------------------------------- tuning
def _tuned_study(tmp_path, **grid):
    part = tiny_grid_part(["sds"], realizations=2, tuning=["paper", "tuned"], noise=[0.05], **grid)
    part["params"]["identify"] = True
    part["tuning"] = {"sds": {"window": ["0.25 s", "1 s"]}}
    return tiny_study(tmp_path, extra_parts={"grid": part})


def _chosen(result) -> list:
    return [(r["candidate"], r["chosen"], r["value"]) for r in result.rows if r["metric"] == "tuning_vaf_output"]


def test_tuning_never_reads_the_scored_realizations_or_the_truth(tmp_path, monkeypatch):
    cases, skipped = expand_study(load_study(_tuned_study(tmp_path)), ["grid"])
    tuned = next(c for c in cases if c.sweep.get("tuning") == "tuned")
    assert len(tuned.params["search"]) == 3       # the paper's 0.5 s first, then 0.25 s and 1 s
    first = run_case(tuned)
    assert first.status == "ok", first.error
    assert sum(c for _, c, _ in _chosen(first)) == 1

    real = sims.simulate

    def scrambled(exp, seed, *a, realization=0, **kw):   # scored realizations replaced by noise
        trial = real(exp, seed, *a, realization=realization, **kw)
        if realization < TUNE_OFFSET:
            noise = np.random.default_rng(realization + 7).standard_normal(len(trial.time))
            trial = trial.replace(torque=noise, angle=noise[::-1].copy())
        return trial

    real_select = compare_mod.select_setting

    def blind_select(make, candidates, fit_data, held_out, keep):
        for trial in (*getattr(fit_data, "realizations", [fit_data]), *held_out):
            assert trial.truth is None             # the tuning data reach the search without their truth
        return real_select(make, candidates, fit_data, held_out, keep)

    monkeypatch.setattr(sims, "simulate", scrambled)
    monkeypatch.setattr(compare_mod, "select_setting", blind_select)
    second = run_case(tuned)
    assert second.status == "ok", second.error
    assert _chosen(second) == _chosen(first)       # the same scores and choice: scored data never used
    vaf = [r["value"] for r in second.rows if r["metric"] == "vaf_stiffness"]
    assert vaf != [r["value"] for r in first.rows if r["metric"] == "vaf_stiffness"]   # the scored part did change


def test_tuned_rows_carry_their_settings_and_pair_by_realization(tmp_path):
    run = run_study(_tuned_study(tmp_path / "c"), parts=["grid"], out_root=tmp_path / "r", serial=True,
                    progress=False)
    assert not run.failed
    rows = run.rows[run.rows["part"] == "grid"]
    est = rows[rows["estimator"] == "sds"]
    assert set(est["tuning"]) == {"paper", "tuned"}
    settings = est.groupby("tuning")["settings"].agg(lambda s: set(s.dropna()))
    assert all(len(v) == 1 for v in settings) and '"window": 0.5' in next(iter(settings["paper"]))
    per = est[est["metric"] == "error_rms"]
    by = {k: sorted(g["realization"]) for k, g in per.groupby("tuning")}
    assert by == {"paper": [0, 1], "tuned": [0, 1]}
    total = est[(est["metric"] == "total_error") & (est["tuning"] == "paper")]["value"].iloc[0]
    assert total == pytest.approx(np.sqrt(np.mean(per[per["tuning"] == "paper"]["value"] ** 2)))
    agg = rows[rows["p05"].notna()]
    assert len(agg) and ((agg["p05"] <= agg["value"]) & (agg["value"] <= agg["p95"])).all()
    scen = rows[rows["estimator"] == "(scenario)"]
    oracle_rows = {"oracle_total_error", "oracle_bias_rms", "oracle_random_error", "oracle_total_error_ensemble"}
    assert set(scen["metric"]) == {"stiffness_share", "tv_share", "noise_share", "tv_snr_db"} | oracle_rows
    ident = scen[~scen["metric"].isin(oracle_rows)]
    assert scen["tuning"].isna().all() and len(ident) == 4          # one resolved experiment
    assert ident.set_index("metric")["value"]["noise_share"] == pytest.approx(5, rel=0.05)   # noise 0.05


# ------------------------------------------------------------------------------- outputs: --set, Parquet
def test_a_set_run_leaves_the_study_results_untouched_and_writes_parquet(tmp_path, monkeypatch, capsys):
    path = tiny_study(tmp_path / "c", extra_parts={"grid": tiny_grid_part(["sds"], realizations=2, noise=[0.05])})
    monkeypatch.chdir(tmp_path)
    own = tmp_path / "results" / "tiny"
    own.mkdir(parents=True)
    (own / "cases.csv").write_text("committed\n")
    run = run_study(path, parts=["grid"], serial=True, progress=False, overrides=["grid.params.realizations=3"])
    assert (own / "cases.csv").read_text() == "committed\n" and sorted(p.name for p in own.iterdir()) == ["cases.csv"]
    assert run.folder.parent == tmp_path / "results" / "set-runs" and run.folder.name.startswith("tiny-set-")
    assert str(run.folder) in capsys.readouterr().err
    pq = pd.read_parquet(run.folder / "cases.parquet")
    csv = pd.read_csv(run.folder / "cases.csv")
    assert len(pq) == len(csv) and {"scenario", "variation", "noise", "backend", "data"} <= set(pq.columns)
    assert pq["noise"].dtype == float and set(pq["scenario"].dropna()) == {"elbow"}
    assert str(pq["realization"].dtype) == "Int64" and set(pq["realization"].dropna()) == {0, 1, 2}
    # the same overrides again: the same folder (the hash of the overrides), never the study's own
    again = run_study(path, parts=["grid"], serial=True, progress=False, overrides=["grid.params.realizations=3"])
    assert again.folder == run.folder


# ---------------------------------------------------------------------------------------- grid rules
def test_only_rules_and_scenario_realizations_shape_the_grid(tmp_path):
    part = tiny_grid_part(["sds", "ibk_spectral"], realizations=2, tuning=["paper", "tuned"], noise=[0, 0.05],
                          backend=["analytic", "ltv"])
    part["tuning"] = {"sds": {"window": ["1 s"]}}
    part["only"] = [{"when": {"backend": "ltv"}, "keep": {"tuning": "paper", "noise": [0]}, "reason": "subset"}]
    part["scenarios"]["elbow"]["realizations"] = 4
    cases, skipped = expand_study(load_study(tiny_study(tmp_path, extra_parts={"grid": part})), ["grid"])
    ltv = [c for c in cases if c.backend == "ltv"]
    assert ltv and all(c.sweep["tuning"] == "paper" and c.sweep["noise"] == 0 for c in ltv)
    why = {(s["backend"], s["estimator"], s["tuning"], s["noise"]): s["reason"] for s in skipped}
    assert why[("ltv", "sds", "tuned", 0)] == "subset" and why[("ltv", "sds", "paper", 0.05)] == "subset"
    assert why[("analytic", "ibk_spectral", "tuned", 0)].startswith("nothing to tune")
    assert all(c.params["realizations"] == 4 for c in cases)
    assert [c.params["search"] for c in cases if c.sweep["tuning"] == "tuned"][0][1]["window"] == "1 s"


@pytest.mark.parametrize("key, value, message", [
    ("only", [{"when": {"colour": "red"}, "keep": {}}], "only[0]: when: unknown key 'colour'; allowed: scenario, "),
    ("only", {"when": {}}, "only[0]: missing required key 'keep'"),
    ("only", [{"keep": {"backend": "analytic"}, "why": "x"}],
     "only[0]: unknown key 'why'; allowed: keep, when, reason"),
    ("tuning", {"sds": {"window": []}}, "tuning.sds.window: expected a value or a non-empty list of values"),
    ("tuning", {"sds": "window"}, "key 'tuning.sds': expected a mapping, got 'window'"),
    ("tuning", {"sds": {"widow": ["1 s"]}}, "tuning of sds (scenario elbow)"),
    ("tuning", {"nosuch": {"window": ["1 s"]}}, "tuning: unknown estimator 'nosuch'"),
])
def test_bad_tuning_and_only_are_config_errors(tmp_path, key, value, message):
    from jointbench.core.errors import ConfigError

    part = tiny_grid_part(["sds"], tuning=["paper", "tuned"])
    part[key] = value
    with pytest.raises(ConfigError, match=message.replace("(", r"\(").replace(")", r"\)").replace("[", r"\[")):
        load_study(tiny_study(tmp_path, extra_parts={"grid": part}))


def test_committed_matrix_rows_have_intervals_that_contain_their_values():
    """Over the committed results/matrix/cases.parquet (written by `make matrix`; skipped before the first
    run that writes it): every aggregate row's 90 % interval contains its value."""
    from pathlib import Path

    path = Path(__file__).resolve().parents[1] / "results" / "matrix" / "cases.parquet"
    if not path.is_file():
        pytest.skip("results/matrix/cases.parquet not committed yet (make matrix writes it)")
    rows = pd.read_parquet(path)
    agg = rows[rows["p05"].notna()]
    assert len(agg) > 0
    bad = agg[~((agg["p05"] <= agg["value"]) & (agg["value"] <= agg["p95"]))]
    assert bad.empty, bad[["case_id", "metric", "value", "p05", "p95"]].head().to_string()


def test_a_tuned_case_is_estimated_to_cost_more_than_its_paper_case(tmp_path):
    from jointbench.benchmarks.compare.grid import estimate_seconds

    cases, _ = expand_study(load_study(_tuned_study(tmp_path)), ["grid"])
    cost = {c.sweep.get("tuning", "identifiability"): estimate_seconds([c], [[0]]) for c in cases}
    # the identifiability case carries the oracle bound (R realizations, x M for its ensembles): no longer
    # cheaper than a paper case
    assert cost["tuned"] > cost["paper"] > 0 and cost["identifiability"] > 0
