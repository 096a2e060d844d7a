"""The nightly raises no false alarm (wall-clock metrics are never a drift) and recomputes every case
unless its config says ``use_cache: true`` (issue 20)."""
from __future__ import annotations

import sqlite3
from pathlib import Path

import yaml

from jointbench.benchmarks.locate import CONFIGS
from jointbench.benchmarks.harness.diff import Rules
from jointbench.benchmarks.nightly import load_config
from jointbench.benchmarks.nightly import run_nightly
from tests.harness_studies import tiny_grid_part, tiny_study


def _config(folder: Path, **edit) -> Path:
    """The shipped nightly config (its thresholds) on a tiny grid study, ``use_cache`` left out."""
    data = yaml.safe_load((CONFIGS / "nightly.yaml").read_text())
    data.pop("use_cache", None)
    data["studies"] = [str(tiny_study(folder / "configs", seeds=1, extra_parts={
        "grid": tiny_grid_part(["ibk_spectral", "irf2_ls"], realizations=2)}))]
    data.update(edit)
    p = folder / "nightly.yaml"
    p.write_text(yaml.safe_dump(data, sort_keys=False))
    return p


def test_a_config_without_use_cache_recomputes(tmp_path):
    assert load_config(_config(tmp_path)).use_cache is False
    assert load_config(_config(tmp_path, use_cache=True)).use_cache is True


def test_nothing_changed_on_a_grid_study_is_no_regression_and_nothing_comes_from_the_cache(tmp_path):
    """Two nightlies of the same code on a comparison grid, with the shipped thresholds: every number is
    identical except the fits' wall-clock times (fit_time_s), which must not count as a drift."""
    cfg = load_config(_config(tmp_path))
    out = tmp_path / "results"
    first = run_nightly(cfg, out, serial=True, progress=False)
    second = run_nightly(cfg, out, serial=True, progress=False)
    assert first.verdict == "baseline" and second.verdict == "ok", second.regressions
    diff = second.outcomes[0].diff
    assert diff is not None and diff.drift.empty
    with sqlite3.connect(out / "history.sqlite") as db:
        cached = db.execute("SELECT SUM(n_cached) FROM runs WHERE kind = 'nightly'").fetchone()[0]
        timed = db.execute("SELECT COUNT(*) FROM results WHERE metric = 'fit_time_s'").fetchone()[0]
    assert cached == 0 and timed > 0           # recomputed (the config left use_cache out), and timed


def test_wall_clock_metrics_are_listed_in_the_shipped_config():
    rules = load_config().rules
    assert rules.is_wall_clock("fit_time_s") and not rules.is_wall_clock("rise_time_s")
    assert Rules().wall_clock == ("fit_time_s",)


def test_an_unknown_study_in_the_nightly_config_is_a_config_error(tmp_path):
    import pytest

    from jointbench.core.errors import ConfigError

    with pytest.raises(ConfigError, match=r"key 'studies': no study 'nope' \(.*nope.*not found\); known: "):
        load_config(_config(tmp_path, studies=["nope"]))
