"""Enough evidence to decide (issue 36): the smallest p-value n paired realizations can give, whether a
family of m pairs can reject after Holm, the realizations that takes; and the summary over scenarios
(Friedman, Nemenyi, the critical-difference diagram) on constructed tables with a known ranking."""
from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from jointbench.benchmarks.compare import pairs as cpairs
from jointbench.benchmarks.compare import stats as cs
from jointbench.benchmarks.compare import summary as csum


# ----------------------------------------------------------------------------- attainable p-values
def test_discordant_p_by_hand_and_against_scipy():
    from scipy import stats

    # n = 4, the smallest difference against the others: W- = 1; P(W <= 1) = |{}, {1}| / 16; two-sided 4/16
    assert cs.discordant_signed_rank_p(4, 1) == pytest.approx(4 / 16)
    # d = 2: W- = 1 + 2 = 3; subsets of 1..n summing to <= 3: {}, {1}, {2}, {3}, {1,2}: 2 * 5 / 2^n
    assert cs.discordant_signed_rank_p(10, 2) == pytest.approx(10 / 1024)
    assert cs.discordant_signed_rank_p(10, 0) == cs.min_signed_rank_p(10) == pytest.approx(2 / 1024)
    for n, d in ((8, 0), (12, 1), (15, 3), (20, 5)):
        x = np.arange(1, n + 1, dtype=float)
        x[:d] *= -1                                   # the d smallest |differences| of the other sign
        assert cs.discordant_signed_rank_p(n, d) == pytest.approx(stats.wilcoxon(x, method="exact").pvalue,
                                                                  rel=1e-9)
    with pytest.raises(ValueError):
        cs.discordant_signed_rank_p(5, 6)


def test_realizations_needed_by_hand():
    # m = 66 pairs: 2/2^11 = 9.8e-4 is above 0.05/66 = 7.6e-4, 2/2^12 = 4.9e-4 below: 12 realizations
    assert not cs.rejection_attainable(11, 66, 0.05)
    assert cs.rejection_attainable(12, 66, 0.05)
    assert cs.realizations_needed(66, 0.05) == 12
    # m = 120: 0.05/120 = 4.2e-4; 2/2^12 = 4.9e-4 is not below it, 2/2^13 = 2.4e-4 is
    assert cs.realizations_needed(120, 0.05) == 13
    # R = 10, the finding: no family of more than 25 pairs can reject (2/1024 >= 0.05/m for m >= 26)
    assert cs.rejection_attainable(10, 25, 0.05) and not cs.rejection_attainable(10, 26, 0.05)
    # the matrix's choice, R = 20: in the largest family (120 pairs) the 5 smallest of 20 differences may
    # point the other way, not 6
    assert cs.rejection_attainable(20, 120, 0.05, discordant=5)
    assert not cs.rejection_attainable(20, 120, 0.05, discordant=6)


def _pairs(n_by_family: dict[str, tuple[int, int]]) -> pd.DataFrame:
    """A pairs frame: family (cell) -> (methods, realizations), no verdicts."""
    recs = []
    for cell, (k, n) in n_by_family.items():
        names = [f"m{i}" for i in range(k)]
        for i, a in enumerate(names):
            for b in names[i + 1:]:
                recs.append({"cell": cell, "tuning": "paper", "metric": "error_rms", "a": a, "b": b, "n": n,
                             "p": 0.5, "p_holm": 1.0, "favours": "a", "verdict": ""})
    return pd.DataFrame(recs)


def test_families_and_their_share_in_the_text():
    p = _pairs({"small": (5, 10), "big": (16, 10), "big R": (16, 20)})      # m = 10, 120, 120
    fam = cpairs.families(p).set_index("cell")
    assert fam.loc["small", "pairs"] == 10 and fam.loc["big", "pairs"] == 120
    assert fam["attainable"].to_dict() == {"small": True, "big": False, "big R": True}
    assert fam.loc["big", "Holm threshold"] == pytest.approx(0.05 / 120)
    text = cpairs.attainability_text(p)
    assert "attainable in 2 of the 3 families (67 %)" in text
    assert "In the 1 others (n = 10 to 10 realizations, m up to 120 pairs)" in text
    assert "its 5 smallest of 20 differences" in text
    assert cpairs.families(pd.DataFrame()).empty and cpairs.attainability_text(pd.DataFrame()) == ""


# ----------------------------------------------------------------------------- summary over scenarios
def _table(values: dict[str, list[float]], metric: str = "total_error", tuning: str = "paper") -> pd.DataFrame:
    """A full table (tables.full_table's columns that the summary reads): method -> value per scenario."""
    recs = []
    for method, vals in values.items():
        for i, v in enumerate(vals):
            recs.append({"cell": f"s{i}", "backend": "analytic", "method": method, "tuning": tuning, "metric": metric,
                         "value": v, "rank": np.nan if np.isnan(v) else 1.0})
    return pd.DataFrame(recs)


def test_friedman_summary_recovers_a_known_ranking():
    # 8 scenarios, A < B < C < D in every one (lower is better): ranks 1, 2, 3, 4 in every block, so
    # Friedman's chi^2 = 12 N / (k (k+1)) sum R_j^2 - 3 N (k+1) = 12*8/20 * 30 - 3*8*5 = N (k - 1) = 24
    rng = np.random.default_rng(0)
    base = rng.uniform(1, 10, 8)
    table = _table({"A": base, "B": base + 1, "C": base + 2, "D": base + 3})
    tests, ranks, posthoc = csum.summarize(table, "analytic")
    t = tests.iloc[0]
    assert (t["scenarios"], t["methods"]) == (8, 4)
    assert t["friedman_chi2"] == pytest.approx(24.0)
    from scipy.stats import chi2
    assert t["p"] == pytest.approx(chi2.sf(24.0, 3)) and t["verdict"] == "methods differ"
    assert ranks["method"].tolist() == ["A", "B", "C", "D"]
    assert ranks["mean_rank"].tolist() == pytest.approx([1, 2, 3, 4])
    # Nemenyi's critical difference q_0.05 sqrt(k (k+1) / (6 N)) = 2.569 * sqrt(20/48) = 1.66: B (1 rank
    # away) cannot be told from A, C and D (2 and 3 away) can
    assert ranks.set_index("method")["tied_with_best"].to_dict() == {"A": True, "B": True, "C": False, "D": False}
    # higher is better for a VAF: the same values rank the other way round
    tests, ranks, _ = csum.summarize(_table({"A": base, "B": base + 1, "C": base + 2, "D": base + 3},
                                            metric="vaf_stiffness"), "analytic")
    assert ranks["method"].tolist() == ["D", "C", "B", "A"]


def test_friedman_summary_without_a_difference():
    # the winner rotates: every method ranks 1..4 equally often: chi^2 = 0, no difference shown
    cyc = [[1, 2, 3, 4], [2, 3, 4, 1], [3, 4, 1, 2], [4, 1, 2, 3]] * 2
    table = _table({m: [row[j] for row in cyc] for j, m in enumerate("ABCD")})
    tests, ranks, _ = csum.summarize(table, "analytic")
    assert tests.iloc[0]["friedman_chi2"] == pytest.approx(0.0)
    assert tests.iloc[0]["verdict"] == "no difference shown"
    assert ranks["tied_with_best"].all()


def test_block_design_drops_what_is_missing_and_names_it():
    nan = np.nan
    # E misses 3 of 4 scenarios, scenario s3 misses 2 of 4 remaining methods
    table = _table({"A": [1, 2, 3, 4], "B": [2, 3, 4, nan], "C": [3, 4, 5, nan], "D": [4, 5, 6, 7],
                    "E": [nan, nan, nan, 1]})
    tests, ranks, _ = csum.summarize(table, "analytic")
    t = tests.iloc[0]
    assert t["left out (methods)"] == "E" and t["left out (scenarios)"] == "s3"
    assert (t["scenarios"], t["methods"]) == (3, 4)
    assert set(ranks["method"]) == {"A", "B", "C", "D"}


def test_too_few_methods_are_not_tested():
    tests, ranks, posthoc = csum.summarize(_table({"A": [1, 2, 3], "B": [2, 3, 4]}), "analytic")
    assert tests.iloc[0]["verdict"].startswith("not tested: 2 methods")
    assert ranks.empty and not posthoc


def test_cd_diagram_files(tmp_path):
    base = np.arange(1.0, 7.0)
    table = _table({"A": base, "B": base + 1, "C": base + 2})
    tests, _, posthoc = csum.summarize(table, "analytic")
    figs = csum.cd_figures(posthoc, tests, "grid", tmp_path, colours={"A": "#1f77b4"})
    assert [f for f, _ in figs] == ["grid_cd_total_error_paper.png"]
    assert (tmp_path / "grid_cd_total_error_paper.png").stat().st_size > 1000
    assert (tmp_path / "grid_cd_total_error_paper.svg").read_text().lstrip().startswith("<?xml")
    assert "Friedman chi^2 = 12" in figs[0][1]            # N (k - 1) = 6 * 2
