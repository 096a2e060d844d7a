"""The report of a comparison grid: the statistics on hand-checkable cases, the full table's intervals
and ranks, and the report made from rows in the study's row format (no simulation)."""
from __future__ import annotations

import json
import math
import re
import types
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from jointbench.benchmarks.compare import stats as cs
from jointbench.benchmarks.compare import figures as compare
from jointbench.benchmarks.compare import tables as ct

REPO = Path(__file__).resolve().parents[1]
COMMITTED = REPO / "results" / "matrix"


# ------------------------------------------------------------------------------- statistics by hand
def test_signed_rank_p_on_hand_counted_cases():
    # all five differences positive: W+ = 15, the largest of 2^5 equally likely sign patterns: p = 2/32
    assert cs.signed_rank_p([1, 2, 3, 4, 5]) == pytest.approx(2 / 32)
    # ranks 1..5 with rank 2 negative: W+ = 13; sums >= 13 are the complements of sums <= 2: {}, {1}, {2}
    assert cs.signed_rank_p([1, -2, 3, 4, 5]) == pytest.approx(2 * 3 / 32)
    # zeros dropped (Wilcoxon's rule); nothing left: no evidence at all
    assert cs.signed_rank_p([0, 0, 1, 2, 3, 4, 5]) == pytest.approx(2 / 32)
    assert cs.signed_rank_p([0.0, 0.0]) == 1.0
    # n = 3, rank 2 negative: W+ = 4; sums >= 4 of {1, 2, 3}: {1,3}, {2,3}, {1,2,3}: p = 2 * 3/8
    assert cs.signed_rank_p([1, -2, 3]) == pytest.approx(2 * 3 / 8)
    assert cs.signed_rank_p([1, -2, -3, 4]) == pytest.approx(1.0)      # W+ = 5 of 0..10: the middle
    assert cs.min_signed_rank_p(10) == pytest.approx(2 / 1024)


def test_signed_rank_p_matches_scipy_exact():
    from scipy import stats

    rng = np.random.default_rng(3)
    for n in (4, 7, 12, 25):
        d = rng.normal(0.4, 1, n)
        assert cs.signed_rank_p(d) == pytest.approx(stats.wilcoxon(d, method="exact").pvalue, rel=1e-9)


def test_holm_by_hand():
    # sorted 0.01, 0.03, 0.04 times 3, 2, 1 = 0.03, 0.06, 0.04 -> non-decreasing: 0.03, 0.06, 0.06
    assert cs.holm([0.01, 0.04, 0.03]).tolist() == pytest.approx([0.03, 0.06, 0.06])
    assert cs.holm([0.5, 0.9]).tolist() == pytest.approx([1.0, 1.0])
    assert cs.holm([]).size == 0


def test_paired_comparisons_hand_checkable():
    # A is below B by 1 to 1.09 in each of 10 realizations (distinct differences of one sign: exact p =
    # 2/1024); C equals B but for alternating +-0.1: lower is better.
    r = range(10)
    b = {i: 5.0 + i for i in r}
    a = {i: b[i] - (1.0 + i / 100) for i in r}
    c = {i: b[i] + (0.1 if i % 2 else -0.1) * (1 + i / 100) for i in r}
    pairs = {(p["a"], p["b"]): p for p in cs.paired_comparisons({"A": a, "B": b, "C": c}, "min")}
    ab = pairs[("A", "B")]
    assert ab["n"] == 10 and ab["median_diff"] == pytest.approx(-1.045) and ab["p"] == pytest.approx(2 / 1024)
    assert ab["p_holm"] == pytest.approx(min(1.0, 3 * 2 / 1024))       # the smallest of 3 p-values, times 3
    assert ab["verdict"] == "a" and ab["favours"] == "a"
    assert -1.09 <= ab["diff_lo"] <= -1.045 <= ab["diff_hi"] <= -1.0      # the paired bootstrap of the median
    assert pairs[("B", "C")]["verdict"] == "" and pairs[("B", "C")]["p"] > 0.5
    # higher is better: the same numbers make B the winner over A
    assert {(p["a"], p["b"]): p for p in cs.paired_comparisons({"A": a, "B": b}, "max")}[("A", "B")]["verdict"] == "b"
    # only shared realizations with finite values pair; none: no comparison
    assert cs.paired_comparisons({"A": {0: 1.0}, "B": {1: 2.0}}, "min") == []
    assert cs.paired_comparisons({"A": {0: math.inf, 1: 1.0}, "B": {0: 1.0, 1: 2.0}}, "min")[0]["n"] == 1


def test_win_counts_over_scenarios():
    s1 = [{"a": "A", "b": "B", "verdict": "a", "favours": "a"}]
    s2 = [{"a": "A", "b": "B", "verdict": "", "favours": "b"}]
    w = cs.win_counts({"s1": s1, "s2": s2})
    assert w[("A", "B")] == {"wins": 1, "ahead": 1, "of": 2}
    assert w[("B", "A")] == {"wins": 0, "ahead": 1, "of": 2}


def test_winner_never_among_non_finite_values():
    assert cs.winner([math.inf, math.nan, 3.0, 5.0], "min") == 2
    assert cs.winner([-math.inf, 1.0, 2.0], "max") == 2                # -inf is not a value to win with
    assert cs.winner([math.inf, math.inf], "min") is None
    assert cs.winner([math.nan], "max") is None
    r = cs.ranks([2.0, math.inf, 1.0, 1.0, math.nan], "min")
    assert r[[0, 2, 3]].tolist() == [3.0, 1.0, 1.0] and np.isnan(r[[1, 4]]).all()


def test_percentile_interval_contains_the_median_and_is_seeded():
    rng = np.random.default_rng(0)
    for k in range(200):
        x = rng.standard_t(2, size=int(rng.integers(2, 30))) * 10 ** rng.uniform(-3, 3)
        lo, hi = cs.bootstrap_interval(x)
        assert cs.contains(lo, float(np.median(x)), hi), (k, x)
    assert cs.bootstrap_interval([4.0, 4.0, 4.0]) == (4.0, 4.0)
    assert cs.bootstrap_interval([1.0, 2.0, 9.0]) == cs.bootstrap_interval([1.0, 2.0, 9.0])
    assert all(math.isnan(v) for v in cs.bootstrap_interval([math.nan]))
    assert cs.contains(math.inf, math.inf, math.inf) and not cs.contains(1.0, math.inf, 2.0)


# ------------------------------------------------------------------------------- rows of the study
def synthetic_rows(R: int = 8, tuned: bool = True, seed: int = 1) -> tuple[pd.DataFrame, pd.DataFrame]:
    """Rows and curves in the study's row format (CONTRACT of the matrix study): three methods on three
    cells (two feasible, one where nobody beats a constant), a square wave where one method never follows
    a step, a constant (time-invariant) fit, both tuning columns with settings, identifiability rows and
    a MuJoCo copy of one cell."""
    rng = np.random.default_rng(seed)
    rows, curves = [], []
    cells = [("wrist", "square", 0.034), ("wrist", "sine", 0.034), ("elbow", "sine", 0.034)]
    methods = {"fast": (80.0, 1.0, 0.4), "slow": (60.0, 2.0, math.inf), "const": (-2.0, 4.0, math.inf)}
    tunings = ("paper", "tuned") if tuned else ("paper",)
    t = np.arange(0, 20, 0.1)
    for scen, var, noise in cells:
        for backend in ("analytic", "mujoco") if (scen, var) == ("wrist", "sine") else ("analytic",):
            base = dict(study="matrix", part="matrix", scenario=scen, variation=var, noise=noise, backend=backend,
                        seed=0, status="ok", data="trial")
            ident = dict(base, estimator="(scenario)", tuning="", settings="", case_id=f"id-{scen}-{var}-{backend}")
            for m, v in (("stiffness_share", 30.0), ("tv_share", 5.0), ("noise_share", 3.0), ("tv_snr_db", 2.0)):
                rows.append(dict(ident, metric=m, value=v if scen == "wrist" else v / 100, n=3))
            truth = 5 + (np.sign(np.sin(2 * np.pi * t / 10)) if var == "square" else np.sin(2 * np.pi * t / 10))
            for name, (vaf, err, rise) in methods.items():
                es = rng.normal(0, 1, R)                  # realization r: the same data in both tuning columns
                for tuning in tunings:
                    case = dict(base, estimator=name, tuning=tuning, case_id=f"{name}-{scen}-{var}-{backend}-{tuning}")
                    if name == "const" and tuning == "tuned":
                        rows.append(dict(case, metric="skipped", value=math.nan, status="ok",
                                         reason="nothing to tune: no smoothing setting", settings=""))
                        continue
                    s = json.dumps({"window": 1.0 if tuning == "paper" else 2.0}, sort_keys=True)
                    case["settings"] = s
                    shift = (-300.0 if scen == "elbow" else 0.0) + (3.0 if tuning == "tuned" else 0.0)
                    shift += 0.001 if backend == "mujoco" else 0.0
                    for r in range(R):
                        e = es[r]
                        rows.append(dict(case, metric="vaf_stiffness", value=vaf + shift + 3 * e, realization=r))
                        rows.append(dict(case, metric="error_rms", value=err * (1 + 0.1 * abs(e)), realization=r))
                        rows.append(dict(case, metric="vaf_output", value=90 + e, realization=r))
                        rows.append(dict(case, metric="fit_time_s", value=0.01 * (1 + 0.1 * r), realization=r))
                    total = err * 1.05
                    agg = {"total_error": total, "bias_rms": err / 2, "bias_mean": -err / 4, "random_error": err / 3}
                    if var == "square":
                        agg["rise_time_s"] = rise
                    for m, v in agg.items():
                        lo, hi = (v, v) if not np.isfinite(v) else (v * 0.9, v * 1.1)
                        if m == "rise_time_s" and name == "fast" and tuning == "tuned":
                            hi = math.inf                 # some resampled sets never follow a step
                        rows.append(dict(case, metric=m, value=v, p05=lo, p95=hi, n=R))
                    if tuning == "tuned":
                        for cand, score in ((1.0, 70.0), (2.0, 75.0)):
                            rows.append(dict(case, metric="tuning_vaf_output", value=score,
                                             candidate=json.dumps({"window": cand}), chosen=cand == 2.0))
                    est = np.full_like(t, truth.mean()) if name == "const" else truth + 0.1 * np.sin(t)
                    for series, y in (("truth", truth), ("mean estimate", est), ("p05 over realizations", est - 0.2),
                                      ("p95 over realizations", est + 0.2)):
                        for x, yy in zip(t, y):
                            curves.append(dict(x=x, y=yy, part="matrix", case_id=case["case_id"], seed=0, scenario=scen,
                                               variation=var, noise=noise, backend=backend, estimator=name,
                                               data="trial", tuning=tuning, curve="stiffness", series=series))
    rows.append(dict(study="matrix", part="matrix", scenario="wrist", variation="sine", noise=0.034, backend="mujoco",
                     estimator="slow", tuning="tuned", metric="skipped", value=math.nan, status="ok", data="trial",
                     reason="M3: MuJoCo runs the paper settings only", case_id="skip-1"))
    return pd.DataFrame(rows), pd.DataFrame(curves)


@pytest.fixture(scope="module")
def report(tmp_path_factory):
    rows, curves = synthetic_rows()
    folder = tmp_path_factory.mktemp("matrix")
    rep = compare.compare_figures(types.SimpleNamespace(name="matrix"), rows, curves, folder, None)
    return rep, folder, rows, curves


def test_full_table_intervals_contain_values_and_ranks_skip_non_finite(report):
    rep, folder, rows, curves = report
    t = pd.read_csv(folder / "matrix_scores.csv")
    shown = t[t["lo"].notna() & t["hi"].notna()]
    assert len(shown) > 50
    assert all(cs.contains(lo, v, hi) for lo, v, hi in zip(shown["lo"], shown["value"], shown["hi"]))
    open_end = t[(t["metric"] == "rise_time_s") & (t["method"] == "fast") & (t["tuning"] == "tuned")]
    assert (open_end["hi"] == math.inf).all() and open_end["lo"].notna().all() and len(open_end)
    rise = t[(t["metric"] == "rise_time_s") & (t["backend"] == "analytic")]
    assert rise["rank"].notna().sum() > 0
    assert not rise[~np.isfinite(rise["value"])]["rank"].notna().any()        # an infinite rise time: no rank
    first = rise[rise["rank"] == 1]
    assert set(first["method"]) == {"fast"} and np.isfinite(first["value"]).all()
    # the constant fit's random error is not ranked; the infeasible cell (elbow) is not ranked at all
    rnd = t[(t["metric"] == "random_error") & (t["method"] == "const") & (t["backend"] == "analytic")]
    assert rnd["rank"].isna().all() and rnd["note"].str.contains("constant estimate|infeasible").all()
    assert t[t["cell"].str.startswith("elbow")]["rank"].isna().all()
    # rankings use the analytic backend only; the tuned column of the constant fit is its paper column
    assert t[t["backend"] == "mujoco"]["rank"].isna().all()
    const_tuned = t[(t["method"] == "const") & (t["tuning"] == "tuned")]
    assert len(const_tuned) and (const_tuned["tuned_as"] == "paper (nothing to tune)").all()


def test_report_text_is_derived_from_the_rows(report):
    rep, folder, rows, curves = report
    text = rep.text
    titles = [t for t, _ in rep.tables]
    assert "3 methods on 3 scenarios" in text and "R = 8 realizations" in text
    assert rep.title.startswith("3 methods on 3 scenarios (2 ranked), R = 8 realizations per case, tuning paper")
    assert "2 base scenarios (wrist, elbow) x 2 stiffness variations (square, sine)" in text
    assert "2 of 3 scenarios are ranked" in text and "elbow / sine" in text
    infeasible = [t for t in titles if t.startswith("elbow / sine")]
    assert len(infeasible) == 1 and "infeasible: not ranked" in infeasible[0]
    assert "SNR of the time-varying" in infeasible[0]                    # shown with its identifiability figures
    assert not re.search(r"studies\.md|issue \d+|#\d\d", text, re.I)        # nothing a reader cannot open
    assert "backend agreement" in text.lower() and text.count("mujoco against analytic") == 1 and "VAF within" in text
    assert any(t.startswith("Identifiability") for t in titles)
    settings = dict(rep.tables)["Settings of every method"]
    assert {"paper", "tuned", "paper (nothing to tune)"} <= set(settings["tuning"])
    assert settings["settings"].str.contains("window=").all()
    assert any(t.startswith("Tuning: candidates") for t in titles)
    effect = [df for t, df in rep.tables if t.startswith("Tuned against paper")][0]
    # the synthetic tuned column is 3 points of VAF above the paper one in every realization of 2 ranked cells
    assert set(effect["method"]) == {"fast", "slow"} and (effect["scenarios"] == 2).all()
    assert (effect["median change of VAF of k (points)"].round(6) == 3.0).all()
    design = [df for t, df in rep.tables if t.startswith("Combinations left out by the grid's design")]
    assert design and dict(zip(*design[0].to_numpy().T)) == {"M3: MuJoCo runs the paper settings only": 1,
                                                           "nothing to tune: no smoothing setting": 4}
    assert not any(t.startswith("Combinations skipped or not fitted") for t in titles)   # design skips only
    # R = 8 and 3 pairs per family: 2/2^8 < 0.05/3, so the test can reject; 'fast' beats 'slow' on error
    assert "`fast` beats `slow`" in text


def test_figures_written_as_png_and_svg(report):
    rep, folder, rows, curves = report
    names = [f for f, _ in rep.figures]
    assert {"matrix_heatmap.png", "matrix_tradeoff.png", "matrix_khat.png", "matrix_heatmap_tuned.png"} <= set(names)
    for f in names:
        assert (folder / f).stat().st_size > 1000 and (folder / f.replace(".png", ".pdf")).stat().st_size > 1000
    # the heat map's scale diverges at 0: the infeasible cell's negative VAF is red, the good ones blue
    import matplotlib.image as mpimg

    px = mpimg.imread(folder / "matrix_heatmap.png")[..., :3]
    red = (px[..., 0] > 0.35) & (px[..., 1] < 0.2) & (px[..., 0] - px[..., 2] > 0.2)
    blue = (px[..., 2] > 0.4) & (px[..., 0] < 0.25) & (px[..., 2] - px[..., 0] > 0.3)
    assert red.mean() > 0.02 and blue.mean() > 0.02
    cap = dict((f, c) for f, c in rep.figures)["matrix_tradeoff.png"]
    assert "rise time infinite for" in cap and "slow" in cap and "const" in cap


def test_rows_before_the_contract_still_make_a_report(tmp_path):
    """Rows without tuning, settings, error_rms, identifiability or a re-centred interval: each section
    says what is missing instead of failing."""
    rows, curves = synthetic_rows(tuned=False)
    rows = rows[(rows["estimator"] != "(scenario)") & (rows["metric"] != "error_rms")]
    rows = rows.drop(columns=["tuning", "settings"])
    bad = rows["metric"] == "bias_rms"
    rows.loc[bad, "p05"] = rows.loc[bad, "value"] * 1.2             # an interval above its value (basic bootstrap)
    rep = compare.compare_figures(types.SimpleNamespace(name="m"), rows, curves.drop(columns="tuning"), tmp_path, None)
    titles = [t for t, _ in rep.tables]
    assert any("no identifiability figures" in t for t in titles)
    assert any("no settings column" in t for t in titles)
    assert "exclude their own value" in rep.text
    t = pd.read_csv(tmp_path / "m_scores.csv")
    assert t[t["metric"] == "bias_rms"]["lo"].isna().all()


def test_committed_scores_intervals_contain_their_values():
    """The committed results/matrix full table: every interval shown contains its value."""
    f = COMMITTED / "matrix_scores.csv"
    if not f.is_file():
        pytest.skip("no committed results/matrix/matrix_scores.csv")
    t = pd.read_csv(f)
    if "interval" not in t.columns:
        pytest.skip("results/matrix/matrix_scores.csv predates the full table (no 'interval' column): "
                    "regenerate with make matrix")
    shown = t[t["lo"].notna() & t["hi"].notna()]
    bad = shown[[not cs.contains(lo, v, hi) for lo, v, hi in zip(shown["lo"], shown["value"], shown["hi"])]]
    assert bad.empty, bad.head().to_string()
    ranked = t[t["rank"].notna()]
    assert np.isfinite(ranked["value"]).all()


def test_committed_rows_give_intervals_that_contain_their_values():
    """From the committed tidy rows (when the results folder holds them): the full table's property."""
    src = next((p for p in (COMMITTED / "cases.parquet", COMMITTED / "cases.csv") if p.is_file()), None)
    if src is None:
        pytest.skip("results/matrix holds no tidy rows (cases.csv / cases.parquet)")
    rows = pd.read_parquet(src) if src.suffix == ".parquet" else pd.read_csv(src, low_memory=False)
    t = ct.full_table(ct.labelled(rows))
    shown = t[t["lo"].notna() & t["hi"].notna()]
    assert all(cs.contains(lo, v, hi) for lo, v, hi in zip(shown["lo"], shown["value"], shown["hi"]))
