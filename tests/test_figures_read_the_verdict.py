"""Pass or miss is decided in one place (benchmarks.checks.verdict): a figure showing a check's bounds reads it,
with the check's own aggregate, never the median (issue 33)."""
import numpy as np
import pandas as pd

from jointbench.benchmarks.checks import judge, verdict
from jointbench.benchmarks.published import Check
from jointbench.benchmarks.studies.vanderuit2018_table1 import figures as T1

SEL = {"metric": "rmse_k", "estimator": "kbr", "variation": "square10", "snr_db": 10.0}


def rows(part: str, values) -> pd.DataFrame:
    return pd.DataFrame([{**SEL, "part": part, "status": "ok", "seed": s, "value": v, "unit": ""}
                         for s, v in enumerate(values)])


def check(aggregate: str, part: str = "table1") -> Check:
    return Check(id="T", part=part, description="", source="", published=5.0, low=4.0, high=6.0, select=SEL,
                 aggregate=aggregate)


def test_the_mean_decides_where_the_check_says_mean():
    r = rows("table1", [5.0, 5.0, 5.0, 5.0, 50.0])      # median 5 (inside), mean 14 (outside)
    assert verdict(check("median"), r)[5] == "pass"
    assert verdict(check("mean"), r)[5] == "miss"
    assert judge((check("mean"),), r, {"table1"})["status"].tolist() == ["miss"]
    # the figure's count of cells met follows the verdict, not the median
    met = T1.within_tolerance(r, {("rmse_k", "kbr", "square10", 10.0): check("mean")})
    assert met["cells within tolerance"].tolist() == ["0 of 1"]
    met = T1.within_tolerance(r, {("rmse_k", "kbr", "square10", 10.0): check("median")})
    assert met["cells within tolerance"].tolist() == ["1 of 1"]


def test_a_check_of_another_part_is_judged_on_this_parts_rows():
    r = rows("sensitivity", [5.0, 5.2, 4.9])
    assert verdict(check("median"), r)[5] == "miss"             # its own part has no rows here: no result
    rep, _, n, _, _, status = verdict(check("median"), r, "sensitivity")
    assert (status, n) == ("pass", 3) and np.isclose(rep, 5.0)
