"""The run history and the cache under locks, full disks, edits and forgeries: one line each, readers never
wait behind a writer, a writer says at once that it waits (issue 20)."""
from __future__ import annotations

import json
import os
import sqlite3
from pathlib import Path

import pytest

from jointbench.benchmarks.harness import fingerprint, history as history_mod
from jointbench.benchmarks.harness.cache import Cache, case_key, prune
from jointbench.benchmarks.harness.history import History
from jointbench.benchmarks.study import run_study
from jointbench.core.errors import ConfigError, OutputError
from tests.harness_studies import cli_here as cli, tiny_study


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    """Two runs of a tiny study in one history (copied by each test that edits it)."""
    root = tmp_path_factory.mktemp("recorded")
    study = tiny_study(root / "cfg", seeds=2)
    for _ in range(2):
        run_study(study, out_root=root / "out", serial=True, progress=False)
    return root / "out"


@pytest.fixture
def out(recorded, tmp_path):
    import shutil

    shutil.copytree(recorded, tmp_path / "out")
    return tmp_path / "out"


def _edit(out: Path, *sql: str) -> None:
    with sqlite3.connect(out / "history.sqlite") as db:
        for s in sql:
            db.execute(s)


def _one_line(r, code=2):
    assert r.returncode == code and r.stderr.count("\n") == 1 and "Traceback" not in r.stderr, r.stderr
    return r.stderr


def test_a_reader_never_waits_behind_a_writer(out, monkeypatch):
    monkeypatch.setattr(history_mod, "LOCK_WAIT_S", 0.05)       # a reader that wrote would fail at once
    writer = sqlite3.connect(out / "history.sqlite", isolation_level=None)
    writer.execute("BEGIN IMMEDIATE")
    try:
        with History(out / "history.sqlite", create=False) as h:
            assert len(h.runs()) == 2 and h.run(1)["status"] == "ok" and len(h.rows(2))
    finally:
        writer.execute("ROLLBACK")
        writer.close()


def test_a_writer_says_that_it_waits_and_for_what(out, monkeypatch, capsys):
    monkeypatch.setattr(history_mod, "LOCK_WAIT_S", 0.2)
    monkeypatch.setattr(history_mod, "QUIET_WAIT_S", 0.05)
    writer = sqlite3.connect(out / "history.sqlite", isolation_level=None)
    writer.execute("BEGIN IMMEDIATE")
    try:
        with pytest.raises(OutputError, match=r"cannot write the run history: database is locked"):
            History(out / "history.sqlite").begin_run("tiny", ["fit"], "x", 1)
    finally:
        writer.execute("ROLLBACK")
        writer.close()
    err = capsys.readouterr().err
    assert "another process is writing the run history" in err and "waiting up to 0.2 s for it" in err


def test_a_lock_released_within_the_quiet_wait_is_not_announced(out, monkeypatch, capsys):
    """Studies side by side write their history rows at about the same moment: a neighbour's write of a
    few tenths of a second is waited for without a word (make reproduce printed it three times)."""
    import threading

    monkeypatch.setattr(history_mod, "QUIET_WAIT_S", 5.0)
    writer = sqlite3.connect(out / "history.sqlite", isolation_level=None, check_same_thread=False)
    writer.execute("BEGIN IMMEDIATE")
    release = threading.Timer(0.3, lambda: writer.execute("ROLLBACK"))
    release.start()
    try:
        run_id = History(out / "history.sqlite").begin_run("tiny", ["fit"], "x", 1)
    finally:
        release.join()
        writer.close()
    assert run_id > 0 and "another process is writing" not in capsys.readouterr().err


def test_a_full_disk_during_the_history_write_is_one_line(out):
    """SQLite rolls a transaction back itself when the disk is full; a second ROLLBACK used to hide the
    error behind 'cannot rollback - no transaction is active'."""
    from jointbench.benchmarks.harness.case import Case, CaseResult

    h = History(out / "history.sqlite")
    run_id = h.begin_run("tiny", ["fit"], "x", 1)
    pages = h.db.execute("PRAGMA page_count").fetchone()[0]
    h.db.execute(f"PRAGMA max_page_count = {pages}")            # the file may not grow: a full disk
    case = Case("tiny", "fit", "parametric_fit", {}, {}, None, {}, 0, "here")
    big = CaseResult(case, "ok", [{"metric": f"m{i}", "value": float(i), "estimator": "x", "pad": "p" * 200}
                                  for i in range(3000)], [], 0.1)
    with pytest.raises(OutputError) as exc:
        h.finish_run(run_id, "ok", [big], {})
    msg = str(exc.value)
    assert "database or disk is full" in msg and "no transaction is active" not in msg and "\n" not in msg
    h.close()


@pytest.mark.parametrize("sql, words", [
    ("UPDATE runs SET parts = 'not json'", "run 1: its 'parts' is not JSON"),
    ("UPDATE runs SET environment = '{'", "run 1: its 'environment' is not JSON"),
])
def test_a_history_with_a_non_json_field_is_one_line(out, sql, words):
    _edit(out, sql)
    assert words in _one_line(cli("history", "1", "--out", out))


@pytest.mark.parametrize("version", ["99", "two"])
def test_a_bad_schema_version_is_one_line(out, version):
    _edit(out, f"UPDATE meta SET value = '{version}' WHERE key = 'schema_version'")
    assert f"history schema version {version!r}" in _one_line(cli("history", "--out", out))
    with pytest.raises(ConfigError, match="schema version"):
        History(out / "history.sqlite")


@pytest.mark.parametrize("args, words", [
    (("history", "1" + "0" * 30), "expected a whole number from 1 to 2**63 - 1, got 1000000000000000000000000000000"),
    (("history", "-1"), "expected a whole number >= 1, got -1"),
    (("diff", "1", "1" + "0" * 30), "expected a whole number from 1 to 2**63 - 1, got 1000000000000000000000000000000"),
])
def test_run_ids_beyond_sqlite_integers_are_one_line(out, args, words):
    assert words in _one_line(cli(*args, "--out", out))


@pytest.mark.parametrize("make, words", [
    (lambda p: p.write_bytes(b"x" * 5000), "file is not a database"),
    (lambda p: os.symlink("/dev/zero", p), "it is a device, not a regular file"),
    (lambda p: p.mkdir(), "it is a folder"),
])
def test_a_history_that_is_not_one_is_one_line(tmp_path, make, words):
    (tmp_path / "out").mkdir()
    make(tmp_path / "out" / "history.sqlite")
    assert words in _one_line(cli("history", "--out", tmp_path / "out"))


def test_a_column_missing_is_one_line(out):
    _edit(out, "ALTER TABLE runs DROP COLUMN wall_s")
    assert "cannot read the run history" in _one_line(cli("history", "--out", out))


def test_diff_labels_checks_of_runs_without_evidence_unrecorded(out):
    """Runs recorded before the kind of evidence was: their checks are 'unrecorded' in the diff, never
    taken for reproductions."""
    from jointbench.benchmarks.harness.diff import diff_runs

    _edit(out, "UPDATE checks SET evidence = NULL", "UPDATE checks SET status = 'miss' WHERE run_id = 1")
    with History(out / "history.sqlite", create=False) as h:
        d = diff_runs(h, 1, 2)
    assert set(d.checks["evidence"]) == {"unrecorded"} and len(d.flipped)
    r = cli("diff", "1", "2", "--out", out)
    assert r.returncode == 0, r.stderr
    flipped = r.stdout.split("checks that changed status")[1].split("metrics that drifted")[0]
    assert "unrecorded" in flipped and "reproduction" not in flipped


def _forge(entry: dict, result) -> dict:
    entry["result"] = result
    entry["checksum"] = fingerprint.sha(result)
    return entry


@pytest.mark.parametrize("forge", [
    lambda e: _forge(e, ["ok"]),
    lambda e: _forge(e, {**e["result"], "rows": 5}),
    lambda e: _forge(e, {**e["result"], "rows": ["a row"]}),
    lambda e: _forge(e, {**e["result"], "rows": [{"value": 1}]}),
    lambda e: [1, 2],
    lambda e: "x",
], ids=["result a list", "rows a number", "rows of strings", "a row without metric", "a list", "a string"])
def test_a_cache_entry_of_the_wrong_type_is_refused_and_recomputed(tmp_path, forge):
    from jointbench.benchmarks.config import load_study
    from jointbench.benchmarks.runner import expand, run_cases

    cases = expand(load_study(tiny_study(tmp_path / "cfg", seeds=1)))
    cache = Cache(tmp_path / "cache")
    first = run_cases(cases, cache, serial=True, progress=False)
    p = cache.path(case_key(cases[0]))
    p.write_text(json.dumps(forge(json.loads(p.read_text()))))
    again = Cache(tmp_path / "cache", warn=lambda m: None)
    second = run_cases(cases, again, serial=True, progress=False)
    assert again.rejected == 1 and not second[0].cached and second[0].rows == first[0].rows


def test_cache_prune_on_a_read_only_cache_is_one_line(tmp_path, monkeypatch):
    folder = tmp_path / "cache" / "ab"
    folder.mkdir(parents=True)
    (folder / ("ab" + "0" * 62 + ".json")).write_text("{}")

    def unlink(self, missing_ok=False):
        raise OSError(30, os.strerror(30))                       # EROFS
    monkeypatch.setattr(Path, "unlink", unlink)
    with pytest.raises(OutputError, match=r"cache: cannot remove cache entries \(Read-only file system; 0 of 1 "
                                          r"removed\)"):
        prune(tmp_path / "cache", keep=set())


def test_a_reader_upgrades_a_version_1_history_once(tmp_path):
    from jointbench.benchmarks.harness.history import SCHEMA

    path = tmp_path / "history.sqlite"
    with sqlite3.connect(path) as db:
        db.executescript(SCHEMA.replace("note TEXT, evidence TEXT, PRIMARY KEY", "note TEXT, PRIMARY KEY"))
        db.execute("INSERT INTO meta VALUES ('schema_version', '1')")
    with History(path, create=False) as h:
        assert h.reader and "evidence" in h.checks(1).columns
    with sqlite3.connect(path) as db:
        assert db.execute("SELECT value FROM meta WHERE key = 'schema_version'").fetchone() == ("2",)


def test_processes_opening_a_new_history_together_all_succeed(tmp_path):
    """Studies side by side (make reproduce) open a fresh history at the same moment: SQLite refuses a change
    of journal mode at once while a neighbour opens the file ("database is locked", without its busy wait);
    it is retried. Four forked processes, released together, ten times (the unretried code failed about one
    process in sixteen)."""
    import time

    failures = []
    for trial in range(10):
        path = tmp_path / f"h{trial}.sqlite"
        go = time.time() + 0.05
        pids = []
        for _ in range(4):
            pid = os.fork()
            if pid == 0:
                code = 1
                try:
                    while time.time() < go:
                        pass
                    with History(path) as h:
                        h.begin_run("tiny", ["fit"], "x", 1)
                    code = 0
                finally:
                    os._exit(code)
            pids.append(pid)
        failures += [pid for pid in pids if os.waitstatus_to_exitcode(os.waitpid(pid, 0)[1]) != 0]
        with History(path) as h:
            assert len(h.runs(limit=None)) == 4 - sum(p in failures for p in pids)
    assert failures == []
