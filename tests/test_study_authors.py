"""What a study author meets (issue 36): a run with --set and no --out writes where the docs say, a study file's
errors come all at once, an unranked scenario says why, and the light install (no MuJoCo extra) runs the analytic
rows of every shipped study and says which rows need the extra."""
from __future__ import annotations

import sys

import pytest

from tests.harness_studies import cli_here, tiny_study


# ------------------------------------------------------------------------------------ --set without --out
def test_jointbench_run_with_set_and_no_out_writes_set_runs_not_the_study_folder(tmp_path, monkeypatch):
    """docs/harness.md and docs/comparison_rows.md: a run with --set and no --out writes
    results/set-runs/<study>-set-<hash8>/ and says so on stderr; the study's own results stay as they were (the
    command line passed its default results folder as if --out had been given, and wrote over them)."""
    path = tiny_study(tmp_path / "c", seeds=1)
    monkeypatch.chdir(tmp_path)
    own = tmp_path / "results" / "tiny"
    own.mkdir(parents=True)
    (own / "checks.csv").write_text("committed\n")
    got = cli_here("run", path, "--serial", "--quiet", "--set", "fit.seeds=2")
    assert got.returncode == 0, got.stderr
    assert sorted(p.name for p in own.iterdir()) == ["checks.csv"] and (own / "checks.csv").read_text() == "committed\n"
    written = list((tmp_path / "results" / "set-runs").glob("tiny-set-*/report.md"))
    assert len(written) == 1, got.stdout
    assert f"outputs in {written[0].parent}" in got.stderr and str(written[0].parent) in got.stdout
    # --out names the folder: the study's own folder when asked for
    again = cli_here("run", path, "--serial", "--quiet", "--set", "fit.seeds=2", "--out", tmp_path / "results")
    assert again.returncode == 0, again.stderr
    assert (own / "report.md").is_file() and (own / "checks.csv").read_text() != "committed\n"
    assert "set-runs" not in again.stderr
