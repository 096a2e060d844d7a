"""Issue 33, the bad-input catalogue's causes 3, 6, 8, 9 and 10, each fed to the code that had it: a plugin
that sleeps forever, calls sys.exit or os._exit (on every executor), a plugin folder holding a yaml.py, failure
reasons at the end of a run, a stuck study lock and a locked history, size checks that count fits, a record
larger than the old row cap, a 0-byte history, a damaged v7.3 .mat file, folders where files are expected, a
numeric part name with --set, a folder where an output file goes."""
from __future__ import annotations

import fcntl
import os
import random
import sqlite3
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest
import yaml

from jointbench.benchmarks.harness import history as history_mod, outputs
from jointbench.core.errors import ConfigError, InputError, OutputError
from tests.harness_studies import cli_here, tiny_study

HOSTILE = Path(__file__).resolve().parent / "catalogue" / "hostile_plugin.py"
MODES = ("ok", "exit", "os_exit", "sleep")        # the hang last: one fresh process fewer to start

pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="forks, POSIX locks")


@pytest.fixture
def hostile_study(tmp_path):
    """A study of four one-case parts, each fitting the hostile plugin in one mode, with a 5 s case limit (it
    counts from when the case is handed to its process: a new process's imports count, seconds on a loaded
    machine)."""
    path = tiny_study(tmp_path / "cfg", seeds=1, estimators={"hostile_test": {"mode": "ok"}})
    data = yaml.safe_load(path.read_text())
    base = data["parts"].pop("fit")
    data["parts"] = {mode: {**base, "estimators": {"hostile_test": {"mode": mode}}} for mode in MODES}
    data.update(plugins=[str(HOSTILE)], case_time_limit="5 s", published=None)
    data.pop("published")
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    yield path
    from jointbench import estimators
    from jointbench.core import plugins

    estimators.REGISTRY._items.pop("hostile_test", None)       # imported anew (and registered) by the next run
    estimators.REGISTRY._tags.pop("hostile_test", None)
    plugins._LOADED.pop(str(HOSTILE), None)
    sys.modules.pop(HOSTILE.stem, None)


@pytest.mark.parametrize("executor", ["serial", "process", pytest.param("dask", marks=pytest.mark.slow)])
def test_a_plugin_that_hangs_or_exits_fails_its_own_case_on_every_executor(hostile_study, tmp_path, executor):
    """Cause 3: sleeping forever times out, sys.exit and os._exit fail their own case with the reason; the
    ok case is kept, the outputs are written, the reasons are printed (cause 6) and the exit status is 1."""
    if executor == "dask":
        pytest.importorskip("distributed")
    out = tmp_path / "out"
    t0 = time.monotonic()
    r = cli_here("run", hostile_study, "--out", out, "--executor", executor, "--workers", "2", "--quiet")
    assert time.monotonic() - t0 < 60, "a case that sleeps forever held the run"
    assert r.returncode == 1, r.stdout + r.stderr
    assert "4 cases (0 from cache, 4 computed), 3 failed" in r.stdout
    err = r.stderr
    assert "failed  sleep-seed0: CaseTimeout: timed out after 5 s (the study's case_time_limit)" in err
    assert "failed  exit-seed0: SystemExit: 3" in err
    assert "failed  os_exit-seed0: CaseProcessDied: the case's process exited with code 0" in err
    assert "ok-seed0" not in err
    folder = out / "tiny"
    assert (folder / "report.md").is_file() and "timed out after 5 s" in (folder / "failures.log").read_text()


def test_the_case_time_limit_is_a_unit_aware_setting(tmp_path):
    from jointbench.benchmarks.config import load_study
    from jointbench.benchmarks.harness.workers import DEFAULT_CASE_TIME_LIMIT_S

    path = tiny_study(tmp_path)
    data = yaml.safe_load(path.read_text())
    assert load_study(path).case_time_limit_s == DEFAULT_CASE_TIME_LIMIT_S
    for given, seconds in (("2 min", 120.0), (45, 45.0), (".inf", float("inf"))):
        path.write_text(yaml.safe_dump({**data, "case_time_limit": yaml.safe_load(given) if given == ".inf"
                                        else given}))
        assert load_study(path).case_time_limit_s == seconds
    for bad, words in (("-1 s", "case_time_limit"), ("3 Hz", "not a time unit|unit"), (0, "case_time_limit")):
        path.write_text(yaml.safe_dump({**data, "case_time_limit": bad}))
        with pytest.raises(ConfigError, match=words):
            load_study(path)


def test_a_plugin_folder_is_appended_so_a_yaml_py_beside_it_replaces_nothing(tmp_path):
    from jointbench.core import plugins

    folder = tmp_path / "plugs"
    folder.mkdir()
    (folder / "yaml.py").write_text("raise RuntimeError('the fake yaml was imported')\n")
    (folder / "colorsys.py").write_text("X = 1\n")               # an installed (stdlib) module's name
    (folder / "my_yaml_user.py").write_text("import yaml\nLOADED = yaml.safe_load('a: 1')\n")
    sys.modules.pop("colorsys", None)
    before = list(sys.path)
    try:
        loaded = plugins.load(str(folder / "my_yaml_user.py"))
        assert loaded.module == "my_yaml_user" and sys.modules["my_yaml_user"].LOADED == {"a": 1}
        assert sys.path[: len(before)] == before and sys.path[-1] == str(folder)
        assert Path(sys.modules["yaml"].__file__).parent != folder
        with pytest.raises(ConfigError, match=r"the name 'colorsys' is taken by the installed module .*rename"):
            plugins.load(str(folder / "colorsys.py"))
    finally:
        sys.path[:] = before
        sys.modules.pop("my_yaml_user", None)


def test_failure_summary_gives_each_reason_on_one_line_and_counts_the_rest():
    from jointbench.benchmarks.runner import failure_summary

    failed = [(f"fit-seed{i}", f"ValueError: bad {i}\nTraceback line") for i in range(7)]
    lines = failure_summary(failed, "results/x/failures.log", shown=5)
    assert lines[:5] == [f"  failed  fit-seed{i}: ValueError: bad {i}" for i in range(5)]
    assert lines[5] == "  ... 2 more in results/x/failures.log" and len(lines) == 6
    assert failure_summary(failed[:2], "log") == [f"  failed  fit-seed{i}: ValueError: bad {i}" for i in range(2)]
    assert failure_summary([("c", "")], "log") == ["  failed  c: (no reason recorded)"]


def _hold_lock(folder: Path, text: bytes) -> int:
    fd = os.open(folder / ".lock", os.O_RDWR | os.O_CREAT, 0o644)
    fcntl.flock(fd, fcntl.LOCK_EX)
    os.pwrite(fd, text, 0)
    return fd


def test_a_stuck_study_lock_ends_the_wait_naming_its_holder_as_printable_text(tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(outputs, "LOCK_WAIT_S", 0.4)
    fd = _hold_lock(tmp_path, b"run 9 (pid 1)\x1b[2J\x07 evil")
    try:
        t0 = time.monotonic()
        with pytest.raises(OutputError, match=r"\.lock: run 9 \(pid 1\)\?\[2J\? evil has held the results' lock "
                                              r"for more than 0\.4 s; if it is stuck, end it"):
            with outputs.study_lock(tmp_path, "run 10"):
                pass
        assert time.monotonic() - t0 < 5
    finally:
        os.close(fd)
    err = capsys.readouterr().err
    assert "\x1b" not in err and "run 9 (pid 1)?[2J? evil is writing the results; waiting up to 0.4 s" in err
    # a holder that finishes within the wait: the lock is taken, and the file names its new holder
    fd = _hold_lock(tmp_path, b"run 11")
    threading.Timer(0.3, os.close, (fd,)).start()
    monkeypatch.setattr(outputs, "LOCK_WAIT_S", 30)
    with outputs.study_lock(tmp_path, "run 12"):
        assert (tmp_path / ".lock").read_text() == "run 12"
    assert "lock acquired after" in capsys.readouterr().err


@pytest.mark.parametrize("create", [False, True])
def test_a_locked_history_says_that_it_waits_and_how_long(tmp_path, monkeypatch, capsys, create):
    path = tmp_path / "history.sqlite"
    history_mod.History(path).close()
    monkeypatch.setattr(history_mod, "LOCK_WAIT_S", 0.5)
    monkeypatch.setattr(history_mod, "QUIET_WAIT_S", 0.1)
    holder = sqlite3.connect(path, isolation_level=None)
    holder.execute("PRAGMA locking_mode = EXCLUSIVE")
    holder.execute("BEGIN EXCLUSIVE")
    holder.execute("UPDATE meta SET value = value")
    try:
        with pytest.raises(OutputError, match="another process has held it locked for more than 0.5 s"):
            history_mod.History(path, create=create)
    finally:
        holder.execute("ROLLBACK")
        holder.close()
    assert "another process holds the run history" in capsys.readouterr().err
    with history_mod.History(path, create=create) as h:            # released: opens at once, silently
        assert h.runs().empty
    assert capsys.readouterr().err == ""


def test_an_empty_history_file_is_no_run_history_yet(tmp_path):
    path = tmp_path / "history.sqlite"
    path.write_bytes(b"")
    with pytest.raises(ConfigError, match=r"no run history yet \(the file is empty"):
        history_mod.History(path, create=False)
    r = cli_here("history", "--out", tmp_path)
    assert r.returncode == 2 and "no run history yet" in r.stderr and "Traceback" not in r.stderr


def test_size_checks_count_fits_not_combinations(tmp_path, monkeypatch):
    """Cause 9: 10^4 combinations x 100 seeds is refused at once; the count is cases x estimators."""
    from jointbench.benchmarks import runner
    from jointbench.benchmarks.config import load_study

    path = tiny_study(tmp_path, seeds=100)
    data = yaml.safe_load(path.read_text())
    data["parts"]["fit"]["sweep"] = {"near_unity": [0.5 + i / 40_000 for i in range(10_000)]}
    path.write_text(yaml.safe_dump(data))
    study = load_study(path)
    t0 = time.monotonic()
    with pytest.raises(ConfigError, match=r"1000000 cases, 1000000 fits .*more than the 100000 fits"):
        runner.expand_study(study)
    assert time.monotonic() - t0 < 2
    # a part of 3 combinations x 4 seeds fitting 2 estimators is 12 cases, 24 fits
    data["parts"]["fit"]["sweep"] = {"near_unity": [0.8, 0.9, 0.95]}
    data["parts"]["fit"]["seeds"] = 4
    data["parts"]["fit"]["estimators"] = {"ibk_spectral": {"fmin": "0 Hz", "fmax": "20 Hz", "segment": "2 s"},
                                          "irf2_ls": {"lag_before": "20 ms", "lag_after": "20 ms"}}
    path.write_text(yaml.safe_dump(data))
    study = load_study(path)
    assert runner.part_size(study.parts["fit"]) == (12, 24)
    monkeypatch.setattr(runner, "MAX_FITS", 23)
    with pytest.raises(ConfigError, match=r"12 cases, 24 fits with their estimators"):
        runner.expand_study(study)
    monkeypatch.setattr(runner, "MAX_FITS", 24)
    assert len(runner.expand_study(study)[0]) == 12


def test_a_grid_counts_its_seeds(tmp_path, monkeypatch):
    from jointbench.benchmarks import runner
    from jointbench.benchmarks.config import load_study
    from tests.harness_studies import tiny_grid_part

    path = tiny_study(tmp_path, extra_parts={"grid": {**tiny_grid_part(["ibk_spectral"]), "seeds": 5}})
    study = load_study(path)
    assert runner.part_size(study.parts["grid"]) == (10, 10)          # 2 noise levels x 5 seeds
    monkeypatch.setattr(runner, "MAX_FITS", 9 + 4)                     # the sweep part: 4 cases, 1 estimator
    with pytest.raises(ConfigError, match=r"14 cases, 14 fits .*\(grid: 10 cases, 10 fits\)"):
        runner.expand_study(study)


def _record(path: Path, n: int, fs: float = 500.0) -> None:
    rng = np.random.default_rng(3)
    t = np.arange(n) / fs
    angle = np.convolve(rng.standard_normal(n), np.ones(10) / 10, "same") * 0.02
    torque = 50 * angle + 0.001 * rng.standard_normal(n)
    np.savetxt(path, np.c_[t, angle, torque], delimiter=",", header="time,angle,torque", comments="", fmt="%.9g")


def test_a_record_is_limited_by_the_memory_its_reading_and_its_method_need_not_its_rows(tmp_path, monkeypatch):
    """Cause 9, at a smaller scale: the old cap refused any record over 5 million rows; now a CSV is read when
    its values fit in half the memory available, and the fit is refused only by the method's own estimate."""
    from jointbench import api
    from jointbench.fitting import read_limits

    assert not hasattr(read_limits, "MAX_SAMPLES") and not hasattr(read_limits, "MAX_VALUES")
    p = tmp_path / "rec.csv"
    n = 20_000
    _record(p, n)
    need = (n + 1) * 3 * read_limits.CSV_BYTES_PER_VALUE
    monkeypatch.setattr(read_limits, "available_memory", lambda: int(1.5 * need))      # half of it: too little
    with pytest.raises(InputError, match=r"rec\.csv: reading it needs more than .* more than half the memory"):
        api.read(p)
    monkeypatch.setattr(read_limits, "available_memory", lambda: 3 * need)
    fit = api.fit("ibk_spectral", p, settings={"fmin": "0 Hz", "fmax": "20 Hz", "segment": "2 s"})
    assert abs(float(np.mean(fit.parameters()["K"])) - 50) < 5                     # a cheap method: accepted
    with pytest.raises(InputError, match=r"kbr: the fit .*need about .* more than half the memory available"):
        api.fit("kbr", p)                                                           # its own estimate refuses


def _mat73(path: Path, n: int = 2000) -> None:
    h5py = pytest.importorskip("h5py")
    t = np.arange(n) / 1000
    with h5py.File(path, "w", userblock_size=512) as f:
        for name, v in (("time", t), ("angle", np.sin(t * 20)), ("torque", np.cos(t * 20))):
            d = f.create_dataset(name, data=v[None, :], chunks=(1, 250), compression="gzip")
            d.attrs["MATLAB_class"] = np.bytes_("double")
    with open(path, "r+b") as fh:
        head = b"MATLAB 7.3 MAT-file, Platform: GLNXA64, Created on: Mon Jan  1 00:00:00 2024 HDF5 schema 1.00 ."
        fh.write(head.ljust(116, b" ") + b"\x00" * 8 + b"\x00\x02" + b"IM")


@pytest.mark.parametrize("seed", [1, 2])
def test_a_damaged_v73_mat_file_is_one_line(tmp_path, seed):
    """Cause 10: bytes of a v7.3 file garbled at random places: read whole, or refused as InputError; never
    h5py's RuntimeError or an AttributeError of a broken link (which seed 1 found among 200 damages)."""
    from jointbench.fitting import read

    good = tmp_path / "good.mat"
    _mat73(good)
    assert read.read_trial(good).n == 2000
    raw, rng, bad = good.read_bytes(), random.Random(seed), tmp_path / "bad.mat"
    refused = 0
    for _ in range(200):
        b = bytearray(raw)
        at = rng.randrange(512, len(b))
        for j in range(rng.choice([1, 8, 64])):
            if at + j < len(b):
                b[at + j] = rng.randrange(256)
        bad.write_bytes(bytes(b))
        try:
            read.read_trial(bad)
        except InputError as exc:
            refused += 1
            assert "\n" not in str(exc)
    assert refused > 100


def test_a_folder_where_a_study_or_its_published_values_are_expected_says_so(tmp_path):
    from jointbench.benchmarks.config import load_study

    (tmp_path / "empty").mkdir()
    with pytest.raises(ConfigError, match=r"empty: is a folder, not a file, and holds no study\.yaml; give a"):
        load_study(tmp_path / "empty")
    path = tiny_study(tmp_path / "cfg")
    data = yaml.safe_load(path.read_text())
    for published in (str(tmp_path / "empty"), "."):
        path.write_text(yaml.safe_dump({**data, "published": published}))
        with pytest.raises(ConfigError, match=r"key 'published': .*: is a folder; the key names a file"):
            load_study(path)


def test_a_numeric_part_name_is_a_config_error_with_overrides_too(tmp_path):
    from jointbench.benchmarks.config import load_study

    path = tiny_study(tmp_path)
    data = yaml.safe_load(path.read_text())
    data["parts"][5] = data["parts"]["fit"]
    data["title"] = 12
    path.write_text(yaml.safe_dump(data))
    for overrides in ((), ("fit.seeds=2",), ("*.seeds=2",)):
        with pytest.raises(ConfigError) as got:
            load_study(path, overrides=overrides)
        assert "key 'parts.5': expected text, got 5" in str(got.value)
        assert "key 'title': expected text, got 12" in str(got.value)


def test_an_output_whose_target_is_a_folder_is_refused_before_anything_moves(tmp_path):
    from jointbench.core.files import replace_as_set

    folder, stage = tmp_path / "results", tmp_path / "stage"
    (stage / "fig").mkdir(parents=True)
    for name in ("cases.csv", "report.md", "fig/a.png"):
        (stage / name).write_text("new")
    folder.mkdir()
    (folder / "cases.csv").write_text("old")
    (folder / "report.md").mkdir()                     # a folder where a file goes
    with pytest.raises(OutputError, match=r"report\.md: is a folder where the outputs write a file"):
        replace_as_set(folder, stage)
    assert (folder / "cases.csv").read_text() == "old" and (stage / "cases.csv").is_file()
    (folder / "report.md").rmdir()
    (folder / "fig").write_text("a file where a folder goes")
    with pytest.raises(OutputError, match=r"fig: is a file where the outputs need a folder"):
        replace_as_set(folder, stage)
    (folder / "fig").unlink()
    assert sorted(p.name for p in replace_as_set(folder, stage)) == ["a.png", "cases.csv", "report.md"]
