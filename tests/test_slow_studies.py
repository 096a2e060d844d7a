"""Exact values of the full studies (marker ``slow``: ``make test-slow``; minutes each on 2 cores).

Each study is run from scratch (no cache) and every check must reproduce the committed
``results/<study>/checks.csv`` exactly: the same status and, to 1e-9 relative, the same reproduced
value. The committed results are regenerated at a clean commit after every change that moves a number,
so a difference here is a change nobody regenerated (or a loss of determinism).
"""
from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from tests.harness_studies import REPO
from jointbench.benchmarks.study import run_study

STUDIES = ("westwick2012", "xu1998", "vanderuit2018_table1")


@pytest.mark.slow
@pytest.mark.parametrize("study", STUDIES)
def test_full_study_reproduces_the_committed_comparison(study, tmp_path):
    committed = pd.read_csv(REPO / "results" / study / "checks.csv")
    if "evidence" not in committed.columns:
        pytest.skip(f"results/{study}/checks.csv predates the current format: regenerate it (make reproduce)")
    run = run_study(study, out_root=tmp_path, use_cache=False, progress=False)
    assert not run.failed, [r.error for r in run.failed]
    now = run.checks.set_index("check")
    old = committed.set_index("check")
    assert list(now.index) == list(old.index)
    assert (now["status"] == old["status"]).all(), list(now.index[now["status"] != old["status"]])
    a, b = now["reproduced"].to_numpy(float), old["reproduced"].to_numpy(float)
    same = np.isclose(a, b, rtol=1e-9, atol=0) | (np.isnan(a) & np.isnan(b)) | (a == b)
    assert same.all(), list(now.index[~same])
