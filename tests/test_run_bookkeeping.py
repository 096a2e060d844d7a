"""What a study run does besides computing its cases: the checks' selections of the tidy rows
(selection.select) and their judging (checks.judge), the curves' frame (tables.curves_frame), a case's
cache entry (cache.Cache) and the Parquet table (outputs.parquet_frame)."""
from __future__ import annotations

import dataclasses

import numpy as np
import pandas as pd
import pytest

from jointbench.benchmarks.config import Check
from jointbench.benchmarks.harness import cache as cache_mod
from jointbench.benchmarks.harness.case import Case, CaseResult
from jointbench.benchmarks.harness.outputs import parquet_frame
from jointbench.benchmarks.selection import select
from jointbench.benchmarks.tables import curves_frame
from jointbench.benchmarks.checks import judge

NAN = float("nan")


def _rows() -> pd.DataFrame:
    """Ten rows of two parts: text with a gap, numbers with inf and NaN, a column mixing kinds."""
    return pd.DataFrame({
        "part": ["p", "p", "p", "p", "p", "p", "q", "q", "p", "p"],
        "status": ["ok", "ok", "ok", "failed", "ok", "ok", "ok", "ok", "ok", "ok"],
        "metric": ["K", "K", "B", "K", "K", "K", "K", "K", "K", "K"],
        "estimator": ["a", "b", "a", "a", NAN, "a", "a", "a", "b", "a"],
        "snr_db": [5.0, 5.0, 5.0, 5.0, 10.0, np.inf, 5.0, 10.0, NAN, 10.0],
        "fs": pd.Series(["native", 100, 250, 100, 250, 100, 100, 100, 250, "native"], dtype=object),
        "flag": [True, False, True, True, True, False, True, True, True, False],
        "value": [1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, NAN, 10.0],
    })


def test_select_by_hand():
    rows = _rows()

    def picked(part, where):
        return select(rows, part, where).index.tolist()

    assert picked("p", {"metric": "K", "estimator": "a"}) == [0, 5, 9]        # row 3 failed
    assert picked("p", {"snr_db": {"ge": 5, "lt": 11}, "metric": "K"}) == [0, 1, 4, 9]
    assert picked("p", {"value": {"le": 5}}) == [0, 1, 2, 4]                   # NaN is in no range
    assert picked("p", {"fs": 100}) == [1, 5]                                  # the text 'native' is no number
    assert picked("p", {"fs": "native"}) == [0, 9]
    assert picked("p", {"snr_db": float("inf")}) == [5]
    assert picked("p", {"flag": True}) == [0, 2, 4, 8]                         # compared as text: 'True'
    assert picked("q", {}) == [6, 7]
    assert picked("r", {}) == []
    none = select(rows, "p", {"metric": "K", "nope": 1})                       # a column the rows lack: none
    assert none.empty and list(none.columns) == list(rows.columns)
    pd.testing.assert_frame_equal(select(rows, "p", {"metric": "K", "estimator": "b"}), rows.iloc[[1, 8]])


def test_compare_scores_value_trend_difference_and_the_rows_outside_the_domain():
    rows = _rows()
    checks = (
        Check(id="v", part="p", description="", source="", published="", select={"metric": "K", "estimator": "a"},
              low=0, high=6, aggregate="median"),
        Check(id="t", part="p", description="", source="", published="", select={"metric": "K", "estimator": "a"},
              low=0, high=0, kind="trend", over="snr_db", direction="increasing", slack=0.0),
        Check(id="d", part="p", description="", source="", published="", select={"metric": "K", "estimator": "a"},
              versus={"metric": "K", "estimator": "b"}, by="snr_db", low=-2, high=2, kind="difference",
              aggregate="mean"),
        Check(id="o", part="p", description="", source="", published="", select={"metric": "K", "estimator": "a"},
              domain={"snr_db": {"lt": 7}}, domain_reason="r", low=0, high=2, aggregate="mean"),
    )
    out = judge(checks, rows, {"p"}).set_index("check")
    # value: K of a in p (rows 0, 5, 9: 1, 6, 10) -> median 6, inside [0, 6]
    assert out.loc["v", "reproduced"] == 6.0 and out.loc["v", "status"] == "pass" and out.loc["v", "n"] == 3
    # trend over snr_db: 5 -> 1, 10 -> 10, inf -> 6: the largest fall is 4 (10 -> 6), above slack 0
    assert out.loc["t", "reproduced"] == 4.0 and out.loc["t", "status"] == "miss"
    # difference a - b at snr_db 5: 1 - 2 (b's 10 dB row is NaN: no group there)
    assert out.loc["d", "reproduced"] == -1.0 and out.loc["d", "spread"] == "snr_db -> 5.0: -1"
    # the domain keeps snr 5 (row 0); outside it: 10 -> 10, inf -> 6
    assert out.loc["o", "reproduced"] == 1.0 and out.loc["o", "out_of_domain"] == "snr_db -> 10.0: 10, inf: 6"


def _case(part="p", seed=0, sweep=None) -> Case:
    return Case(study="s", part=part, protocol="x", params={}, sweep=sweep or {}, experiment=None,
                estimators={}, seed=seed, where="w")


def _curves_results() -> list[CaseResult]:
    a = {"curve": "k", "series": "truth", "x": [0.0, 1.0], "y": [2.0, 3.0]}
    b = {"curve": "k", "series": "est", "n": 3, "x": [0.0, 1.0, 2.0], "y": [4.0, 5.0, 6.0]}
    ints = {"curve": "lags", "series": "h", "x": np.arange(3), "y": np.array([0.5, 0.25, 0.125])}
    flag = {"curve": "k", "series": "on", "ok": True, "x": [1.0], "y": [1.0]}
    mixed = {"curve": "k", "series": "odd", "x": [1, 2.5], "y": [1.0, 2.0]}
    return [CaseResult(_case(seed=0, sweep={"snr": 5.0}), "ok", [], [a, b, ints], 0.0),
            CaseResult(_case(seed=1, sweep={"snr": 10.0}), "ok", [], [b, a, flag, mixed, a], 0.0),
            CaseResult(_case(part="q", seed=2), "ok", [], [ints, a], 0.0)]


def test_the_curves_frame_has_a_row_per_point_in_the_curves_order():
    results = _curves_results()
    got = curves_frame(results)
    # the rows in the curves' order, columns in order of appearance, a missing label empty
    assert list(got.columns) == ["x", "y", "part", "case_id", "seed", "snr", "curve", "series", "n", "ok"]
    assert got["series"].tolist()[:8] == ["truth"] * 2 + ["est"] * 3 + ["h"] * 3
    assert got["seed"].tolist() == [0] * 8 + [1] * 10 + [2] * 5
    assert got["n"].dtype == float and got["n"].isna().sum() == len(got) - 6
    assert got["ok"].dtype == object and got["ok"].tolist().count(True) == 1
    assert got["snr"].iloc[-5:].isna().all() and got["snr"].iloc[:18].tolist() == [5.0] * 8 + [10.0] * 10


def test_the_curves_frame_of_like_curves_of_none_and_of_a_bad_one():
    one = [CaseResult(_case(seed=s), "ok", [], [{"curve": "c", "series": "s", "x": [0.0, 1.0], "y": [1.0, 2.0]}],
                      0.0) for s in range(3)]
    got = curves_frame(one)
    assert got["case_id"].tolist() == ["p-seed0"] * 2 + ["p-seed1"] * 2 + ["p-seed2"] * 2
    assert list(curves_frame([]).columns) == ["part", "case_id", "seed", "curve", "series", "x", "y"]
    bad = [CaseResult(_case(), "ok", [], [{"curve": "c", "x": [0.0, 1.0], "y": [1.0]}], 0.0)]
    with pytest.raises(ValueError):                       # x and y of two lengths: an error
        curves_frame(bad)


def test_a_stored_case_is_read_back_under_its_key(tmp_path):
    case = _case()
    cache = cache_mod.Cache(tmp_path / "cache")
    key = cache_mod.case_key(case)
    assert cache.get(case) is None and not cache.path(key).exists()
    assert cache_mod.case_key(dataclasses.replace(case, seed=1)) != key       # another seed, another key
    rows = [{"estimator": "e", "metric": "K", "value": 1.5}]
    cache.put(CaseResult(case, "ok", rows, [], 0.1))
    assert cache.path(key).is_file() and cache.written == 1
    again = cache_mod.Cache(tmp_path / "cache", warn=lambda m: None)
    assert again.get(case).rows == rows and again.hits == 1 and again.rejected == 0


def test_the_parquet_table_leaves_text_columns_as_they_are():
    rows = pd.DataFrame({"a": pd.Series(["x", NAN, "y"], dtype="str"), "b": pd.Series([NAN] * 3, dtype="str"),
                         "c": pd.Series(["1.5", None, 2.5], dtype=object), "seed": [1.0, 2.0, 3.0]})
    out = parquet_frame(rows)
    pd.testing.assert_series_equal(out["a"], rows["a"])                  # text and NaN: unchanged
    assert out["b"].dtype == object and out["b"].tolist() == [None] * 3  # no text at all: missing values
    assert out["c"].fillna("-").tolist() == ["1.5", "-", "2.5"] and str(out["seed"].dtype) == "Int64"
