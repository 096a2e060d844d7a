"""Issue 19, fidelity: each published number counted once (method differences on their own line), and the
evidence kinds the issue corrected, read from the published configs."""
from __future__ import annotations

import pandas as pd
import pytest

from jointbench.benchmarks.config import load_study
from jointbench.benchmarks.tables import difference_counts, evidence_counts, headline


def _comp(statuses, evidence, counts):
    return pd.DataFrame({"check": [f"c{i}" for i in range(len(statuses))], "status": statuses,
                         "evidence": evidence, "count": counts})


def test_a_method_difference_never_adds_to_the_headline():
    base = _comp(["pass", "miss"], ["reproduction"] * 2, ["headline"] * 2)
    assert evidence_counts(base) == {"reproduction": (1, 2)}
    assert difference_counts(base) is None
    for status in ("pass", "miss"):
        more = pd.concat([base, _comp([status], ["reproduction"], ["method_difference"]).assign(check="d")])
        assert evidence_counts(more) == {"reproduction": (1, 2)}          # the headline does not move
        assert difference_counts(more) == (int(status == "pass"), 1)
        assert headline(more).startswith(f"reproduction 1 of 2 pass; method differences {int(status == 'pass')} of 1")
    old = base.drop(columns="count")            # a comparison written before the count column: all headline
    assert evidence_counts(old) == {"reproduction": (1, 2)}


def _checks(study):
    return {c.id: c for c in load_study(study).checks}


@pytest.fixture(scope="module")
def table1_checks():
    return _checks("vanderuit2018_table1")


def test_table1_gap_checks_are_method_differences_and_cells_are_not(table1_checks):
    d = [c for c in table1_checks.values() if c.id.startswith("D-")]
    assert d and all(c.count == "method_difference" and c.kind == "difference" for c in d)
    assert all(c.count == "headline" for c in table1_checks.values() if not c.id.startswith("D-"))
    # the near-copies of their sign checks are gone (inner edge of the band below a quarter of the gap)
    for gone in ("D-square20-5-rmse_k-size", "D-square10-5-rmse_k-size"):
        assert gone not in table1_checks and gone.replace("-size", "-sign") in table1_checks
