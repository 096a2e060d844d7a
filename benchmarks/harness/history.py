"""The run history: every run of every study in one SQLite file, ``results/history.sqlite``.

Tables: ``runs`` (study, parts, config hash, code hash, commit and dirty flag, Python and package
versions, machine, start and end, status), ``cases`` (one per case of a run: status, error, wall time,
whether it came from the cache, its cache key), ``results`` (the tidy rows: estimator, metric, value and
the case's labels as JSON), ``checks`` (the comparison with the published values: each check's outcome
with its kind of evidence) and ``nightlies`` (one per ``jointbench nightly``, grouping its runs).

Writes are transactional (WAL journal, so readers never block a writer and two runs can write at once):
a run row is created with status ``running`` when the run starts, and its cases, rows, checks and final
status (``ok``, ``interrupted``, ``error``) are written in **one** transaction at its end. A crash before
or during that transaction leaves only the ``running`` row, which is shown as ``crashed`` once its
process is gone: a half-written run never looks complete, and a case is recorded once per run (the
primary key of ``cases`` forbids a second copy). A run stopped by Ctrl-C records the cases it finished,
with status ``interrupted``.
"""
from __future__ import annotations

import contextlib
import datetime as _dt
import json
import math
import os
import socket
import sqlite3
import sys
from pathlib import Path
from typing import Iterable

import pandas as pd

from jointbench.benchmarks.harness import fingerprint
from jointbench.benchmarks.harness.case import CaseResult
from jointbench.core.errors import ConfigError, OutputError
from jointbench.core.files import pid_alive

SCHEMA_VERSION = 2             # 2: checks.evidence (a version-1 history gains the column, NULL for old runs)
SCHEMA = """
CREATE TABLE IF NOT EXISTS meta (key TEXT PRIMARY KEY, value TEXT NOT NULL);
CREATE TABLE IF NOT EXISTS nightlies (
    id INTEGER PRIMARY KEY AUTOINCREMENT, started TEXT NOT NULL, ended TEXT, status TEXT NOT NULL,
    commit_id TEXT, dirty INTEGER, config_hash TEXT, verdict TEXT, summary TEXT, process TEXT);
CREATE TABLE IF NOT EXISTS runs (
    id INTEGER PRIMARY KEY AUTOINCREMENT, study TEXT NOT NULL, kind TEXT NOT NULL,
    nightly_id INTEGER REFERENCES nightlies(id), parts TEXT NOT NULL, config_hash TEXT NOT NULL,
    code_hash TEXT NOT NULL, commit_id TEXT NOT NULL, dirty INTEGER NOT NULL, python TEXT NOT NULL,
    environment TEXT NOT NULL, machine TEXT NOT NULL, command TEXT, workers INTEGER,
    started TEXT NOT NULL, ended TEXT, status TEXT NOT NULL, process TEXT,
    n_cases INTEGER NOT NULL, n_done INTEGER NOT NULL DEFAULT 0, n_failed INTEGER, n_cached INTEGER,
    wall_s REAL, error TEXT);
CREATE TABLE IF NOT EXISTS cases (
    run_id INTEGER NOT NULL REFERENCES runs(id), case_id TEXT NOT NULL, part TEXT NOT NULL,
    seed INTEGER NOT NULL, cache_key TEXT, status TEXT NOT NULL, error TEXT, wall_time_s REAL,
    cached INTEGER NOT NULL, labels TEXT NOT NULL, PRIMARY KEY (run_id, case_id));
CREATE TABLE IF NOT EXISTS results (
    run_id INTEGER NOT NULL, case_id TEXT NOT NULL, estimator TEXT NOT NULL, metric TEXT NOT NULL,
    value REAL, labels TEXT NOT NULL, FOREIGN KEY (run_id, case_id) REFERENCES cases(run_id, case_id));
CREATE INDEX IF NOT EXISTS results_run ON results(run_id);
CREATE TABLE IF NOT EXISTS checks (
    run_id INTEGER NOT NULL REFERENCES runs(id), check_id TEXT NOT NULL, part TEXT, metric TEXT,
    description TEXT, published TEXT, reproduced REAL, low REAL, high REAL, status TEXT, aggregate TEXT,
    n INTEGER, spread TEXT, note TEXT, evidence TEXT, PRIMARY KEY (run_id, check_id));
CREATE INDEX IF NOT EXISTS runs_study ON runs(study, id);
"""
FINAL = ("ok", "interrupted", "error")
#: seconds a writer waits for another process's write transaction (it says so after QUIET_WAIT_S)
LOCK_WAIT_S = 60
#: seconds a writer waits without a word first: another run's write usually takes milliseconds (studies
#: side by side start and end together: make reproduce printed the message three times on a fresh clone)
QUIET_WAIT_S = 1.0
#: run ids are SQLite integers
MAX_RUN_ID = 2 ** 63 - 1


def now() -> str:
    return _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds")


def _start_time(pid: int) -> str:
    try:
        with open(f"/proc/{pid}/stat", "rb") as f:
            return f.read().rsplit(b")", 1)[1].split()[19].decode()
    except (OSError, IndexError):
        return ""


def process_token() -> str:
    """host:pid:start time of this process (tells a live run from a crashed one)."""
    pid = os.getpid()
    return f"{socket.gethostname()}:{pid}:{_start_time(pid)}"


def _token_alive(token: str | None) -> bool:
    if not token:
        return False
    host, _, rest = token.partition(":")
    pid, _, start = rest.partition(":")
    if host != socket.gethostname():
        return True                      # another machine's run: cannot tell, assume alive
    if not pid.isdigit() or not pid_alive(int(pid)):
        return False
    return not start or _start_time(int(pid)) == start


#: free space below which an SQLite I/O error is reported as a full disk
LOW_SPACE = 1 << 20


def _why(exc: sqlite3.Error, path: Path | None = None) -> str:
    """SQLite's message, with the cause when it is a full disk (SQLite says 'database or disk is full', or
    only 'disk I/O error' when its shared-memory file cannot grow)."""
    text = str(exc)
    if "disk" in text and "full" in text:
        return text + " (no space left on the device)"
    if path is not None and ("I/O" in text or "disk" in text):
        import shutil

        try:
            free = shutil.disk_usage(Path(path).parent).free
        except OSError:
            return text
        if free < LOW_SPACE:
            text += f" (no space left on the device: {free // 1024} kB free)"
    return text


def _locked(exc: sqlite3.Error) -> bool:
    """SQLite's answer when another process holds the lock it needs."""
    return "locked" in str(exc) or "busy" in str(exc)


def _num(v) -> float | None:
    try:
        v = float(v)
    except (TypeError, ValueError):
        return None
    return None if math.isnan(v) else v


class History:
    """One history file. Every method opens its own short transaction.

    ``create=False`` opens it to read (``jointbench history``, ``diff``): nothing is written, so a reader
    never waits behind another process's write. A writer that finds the history locked by another
    process waits a second quietly, then says so and waits up to :data:`LOCK_WAIT_S` (:meth:`_tx`)."""

    def __init__(self, path: Path, create: bool = True):
        from jointbench.core.files import file_problem

        self.path = Path(path)
        self.reader = not create
        problem = file_problem(self.path)
        if problem == "file not found" and not create:
            raise ConfigError(f"{self.path}: no run history yet (it is written by `jointbench run` and "
                              "`jointbench nightly`)")
        if problem is None and not create and self.path.stat().st_size == 0:
            raise ConfigError(f"{self.path}: no run history yet (the file is empty; `jointbench run` and "
                              "`jointbench nightly` write it)")
        if problem is not None and problem != "file not found":
            raise OutputError(f"{self.path}: cannot use the run history: it {problem}")
        try:
            try:
                self._open(min(QUIET_WAIT_S, LOCK_WAIT_S), create)
            except sqlite3.OperationalError as exc:
                if not _locked(exc):
                    raise
                self.db.close()
                print(f"jointbench: {self.path}: another process holds the run history (a run or nightly "
                      f"recording its results, `jointbench cache prune`, or an SQLite shell); waiting up to "
                      f"{LOCK_WAIT_S} s for it", file=sys.stderr, flush=True)
                self._open(LOCK_WAIT_S, create)
        except sqlite3.Error as exc:
            why = (f"another process has held it locked for more than {LOCK_WAIT_S} s; try again when it has "
                   f"finished (or end it)" if isinstance(exc, sqlite3.OperationalError) and _locked(exc)
                   else _why(exc, self.path))
            raise OutputError(f"{self.path}: cannot use the run history: {why}") from None
        self._mark_crashed()

    def _open(self, wait_s: float, create: bool) -> None:
        """Connect, check the schema version (a reader) or create and upgrade the tables (a writer),
        waiting at most ``wait_s`` for another process's lock (then ``sqlite3.OperationalError``)."""
        self.db = sqlite3.connect(self.path, timeout=wait_s, isolation_level=None)
        self.db.row_factory = sqlite3.Row
        self.db.execute(f"PRAGMA busy_timeout = {int(wait_s * 1000)}")
        version = SCHEMA_VERSION
        if self.reader:
            row = (self.db.execute("SELECT value FROM meta WHERE key = 'schema_version'").fetchone()
                   if self._has_meta() else None)
            version = self._check_version(row)
            self.reader = version != 1           # a version-1 history is upgraded once, even by a reader
        if not self.reader:
            self._wal(wait_s)
            self.db.execute("PRAGMA synchronous = NORMAL")
            self.db.execute("PRAGMA foreign_keys = ON")
            with self._tx():
                for stmt in SCHEMA.split(";"):
                    if stmt.strip():
                        self.db.execute(stmt)
                row = self.db.execute("SELECT value FROM meta WHERE key = 'schema_version'").fetchone()
                if row is None:
                    self.db.execute("INSERT INTO meta VALUES ('schema_version', ?)", (str(SCHEMA_VERSION),))
                elif self._check_version(row) == 1:
                    self.db.execute("ALTER TABLE checks ADD COLUMN evidence TEXT")
                    self.db.execute("UPDATE meta SET value = ? WHERE key = 'schema_version'",
                                    (str(SCHEMA_VERSION),))
            self.reader = not create
        self.db.execute(f"PRAGMA busy_timeout = {int(LOCK_WAIT_S * 1000)}")

    def _wal(self, wait_s: float = LOCK_WAIT_S) -> None:
        """``PRAGMA journal_mode = WAL``, retried while another process holds the file: SQLite answers a
        change of journal mode with "database is locked" at once, without its busy wait, when a neighbour is
        opening the same new history (studies side by side start together; one of them failed so)."""
        import time

        deadline = time.monotonic() + wait_s
        while True:
            try:
                self.db.execute("PRAGMA journal_mode = WAL")
                return
            except sqlite3.OperationalError as exc:
                if ("locked" not in str(exc) and "busy" not in str(exc)) or time.monotonic() > deadline:
                    raise
                time.sleep(0.02)

    def _has_meta(self) -> bool:
        return self.db.execute("SELECT 1 FROM sqlite_master WHERE type = 'table' AND name = 'meta'").fetchone() \
            is not None

    def _check_version(self, row) -> int:
        """The schema version of ``row`` (1 or this code's); any other is a one-line error."""
        if row is None:
            if self.reader and not self._has_meta():
                raise OutputError(f"{self.path}: not a run history of jointbench (no 'meta' table)")
            return SCHEMA_VERSION
        try:
            version = int(row[0])
        except (TypeError, ValueError):
            version = None
        if version not in (1, SCHEMA_VERSION):
            raise ConfigError(f"{self.path}: history schema version {row[0]!r}, this code reads {SCHEMA_VERSION} "
                              f"(and upgrades 1); the file was written by other code or edited")
        return version

    def close(self) -> None:
        self.db.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def _begin(self) -> None:
        """BEGIN IMMEDIATE; when another process holds the write lock, wait :data:`QUIET_WAIT_S` quietly,
        then say so and wait up to :data:`LOCK_WAIT_S`."""
        quiet = min(QUIET_WAIT_S, LOCK_WAIT_S)
        self.db.execute(f"PRAGMA busy_timeout = {int(quiet * 1000)}")
        try:
            self.db.execute("BEGIN IMMEDIATE")
            return
        except sqlite3.OperationalError as exc:
            if "locked" not in str(exc) and "busy" not in str(exc):
                raise
        finally:
            self.db.execute(f"PRAGMA busy_timeout = {int(LOCK_WAIT_S * 1000)}")
        print(f"jointbench: {self.path}: another process is writing the run history (a run or nightly "
              f"recording its results, or `jointbench cache prune`); waiting up to {LOCK_WAIT_S} s for it",
              file=sys.stderr, flush=True)
        self.db.execute("BEGIN IMMEDIATE")

    def _rollback(self) -> None:
        """ROLLBACK if a transaction is still open (SQLite ends it itself on some errors, a full disk
        among them: a second ROLLBACK would say 'no transaction is active' and hide the first error)."""
        if self.db.in_transaction:
            try:
                self.db.execute("ROLLBACK")
            except sqlite3.Error:
                pass

    @contextlib.contextmanager
    def _tx(self):
        """BEGIN IMMEDIATE ... COMMIT, rolled back on any exception (KeyboardInterrupt included); every
        SQLite error is one line naming the history and the cause."""
        if self.reader:
            raise OutputError(f"{self.path}: opened to read; cannot write the run history")
        try:
            self._begin()
        except sqlite3.Error as exc:
            raise OutputError(f"{self.path}: cannot write the run history: {_why(exc, self.path)}") from None
        try:
            yield self.db
        except sqlite3.Error as exc:
            self._rollback()
            raise OutputError(f"{self.path}: cannot write the run history: {_why(exc, self.path)}") from None
        except BaseException:
            self._rollback()
            raise
        try:
            self.db.execute("COMMIT")
        except sqlite3.Error as exc:
            self._rollback()
            raise OutputError(f"{self.path}: cannot write the run history: {_why(exc, self.path)}") from None

    def _mark_crashed(self) -> None:
        """Runs (and nightlies) still 'running' whose process is gone are 'crashed' (a reader shows them
        so without writing it down)."""
        self._crashed: dict[str, set] = {}
        for table in ("runs", "nightlies"):
            try:
                rows = self.db.execute(f"SELECT id, process FROM {table} WHERE status = 'running'").fetchall()
            except sqlite3.Error as exc:
                raise OutputError(f"{self.path}: cannot read the run history: {_why(exc, self.path)}") from None
            dead = [r["id"] for r in rows if not _token_alive(r["process"])]
            self._crashed[table] = set(dead)
            if dead and not self.reader:
                try:
                    with self._tx():
                        self.db.executemany(f"UPDATE {table} SET status = 'crashed' WHERE id = ? AND "
                                            "status = 'running'", [(i,) for i in dead])
                except OutputError:
                    pass                  # a read-only history still reads

    # ------------------------------------------------------------------ writing
    def begin_run(self, study: str, parts: list[str], config_hash: str, n_cases: int, *, kind: str = "run",
                  nightly_id: int | None = None, command: str = "", workers: int | None = None,
                  plugins: dict[str, str] | None = None) -> int:
        """Record a run's start (status ``running``); its id. ``plugins``: the plugin estimators its cases
        use, estimator -> ``"<distribution>==<version> <source hash>"``
        (:func:`~benchmarks.harness.fingerprint.plugin_hash`), recorded as the environment's ``plugins`` in
        place of every plugin loaded in the process (what ``jointbench diff`` compares)."""
        commit, dirty = fingerprint.git_state()
        env = fingerprint.environment()
        if plugins is not None:
            env.pop("plugins", None)
            if plugins:
                env["plugins"] = dict(plugins)
        with self._tx():
            cur = self.db.execute(
                "INSERT INTO runs (study, kind, nightly_id, parts, config_hash, code_hash, commit_id, dirty, "
                "python, environment, machine, command, workers, started, status, process, n_cases) "
                "VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, 'running', ?, ?)",
                (study, kind, nightly_id, json.dumps(parts), config_hash, fingerprint.code_hash(), commit,
                 int(dirty), env["python"], json.dumps(env, sort_keys=True), f"{env['host']} ({env['machine']}, "
                 f"{env['cpus']} cpus)", command, workers, now(), process_token(), n_cases))
            return int(cur.lastrowid)

    def progress(self, run_id: int, n_done: int) -> None:
        with self._tx():
            self.db.execute("UPDATE runs SET n_done = ? WHERE id = ?", (n_done, run_id))

    def finish_run(self, run_id: int, status: str, results: Iterable[CaseResult], keys: dict[str, str],
                   comparison: pd.DataFrame | None = None, check_metrics: dict[str, str] | None = None,
                   wall_s: float | None = None, error: str = "") -> None:
        """Record the run's cases, rows and checks and its final status, in one transaction."""
        if status not in FINAL:
            raise ValueError(f"status {status!r}; allowed: {FINAL}")
        results = list(results)
        cases, rows = [], []
        for r in results:
            c = r.case
            case_id = c.case_id                 # a property that formats the sweep: once per case, not per row
            labels = json.dumps(dict(c.sweep), sort_keys=True, default=str)
            cases.append((run_id, case_id, c.part, c.seed, keys.get(case_id), r.status, r.error,
                          r.wall_time_s, int(r.cached), labels))
            for row in r.rows:
                extra = {k: v for k, v in row.items() if k not in ("metric", "value", "estimator")}
                rows.append((run_id, case_id, str(row.get("estimator") or ""), str(row["metric"]),
                             _num(row.get("value")),
                             json.dumps({**c.sweep, **extra}, sort_keys=True, default=str)))
        checks = []
        if comparison is not None and len(comparison):
            for r in comparison.to_dict("records"):
                checks.append((run_id, r["check"], r.get("part"), (check_metrics or {}).get(r["check"]),
                               r.get("description"), json.dumps(r.get("published"), default=str),
                               _num(r.get("reproduced")), _num(r.get("low")), _num(r.get("high")),
                               r.get("status"), r.get("aggregate"), int(r.get("n") or 0), r.get("spread"),
                               r.get("note"), r.get("evidence")))
        n_failed = sum(r.status == "failed" for r in results)        # refused cases are counted apart
        n_cached = sum(bool(r.cached) for r in results)
        with self._tx():
            st = self.db.execute("SELECT status FROM runs WHERE id = ?", (run_id,)).fetchone()
            if st is None or st[0] not in ("running", "crashed"):
                raise RuntimeError(f"run {run_id} is not running (status {st and st[0]})")
            self.db.executemany("INSERT INTO cases VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?)", cases)
            self.db.executemany("INSERT INTO results VALUES (?, ?, ?, ?, ?, ?)", rows)
            self.db.executemany("INSERT INTO checks (run_id, check_id, part, metric, description, published, "
                                "reproduced, low, high, status, aggregate, n, spread, note, evidence) "
                                "VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?)", checks)
            self.db.execute("UPDATE runs SET status = ?, ended = ?, n_done = ?, n_failed = ?, n_cached = ?, "
                            "wall_s = ?, error = ? WHERE id = ?",
                            (status, now(), len(results), n_failed, n_cached, wall_s, error, run_id))

    def begin_nightly(self, config_hash: str) -> int:
        commit, dirty = fingerprint.git_state()
        with self._tx():
            cur = self.db.execute("INSERT INTO nightlies (started, status, commit_id, dirty, config_hash, process) "
                                  "VALUES (?, 'running', ?, ?, ?, ?)",
                                  (now(), commit, int(dirty), config_hash, process_token()))
            return int(cur.lastrowid)

    def finish_nightly(self, nightly_id: int, status: str, verdict: str, summary: dict) -> None:
        with self._tx():
            self.db.execute("UPDATE nightlies SET status = ?, ended = ?, verdict = ?, summary = ? WHERE id = ?",
                            (status, now(), verdict, json.dumps(summary, default=str), nightly_id))

    # ------------------------------------------------------------------ reading
    def _query(self, q: str, db=None, params=()) -> pd.DataFrame:
        """A query as a table; a damaged or foreign history is one line, not a traceback."""
        try:
            return pd.read_sql_query(q, self.db, params=list(params))
        except (sqlite3.Error, pd.errors.DatabaseError) as exc:
            why = _why(exc, self.path) if isinstance(exc, sqlite3.Error) else " ".join(str(exc).split())
            raise OutputError(f"{self.path}: cannot read the run history: {why}; "
                              "the file was written by other code or damaged") from None

    def runs(self, study: str | None = None, kind: str | None = None, limit: int | None = 50) -> pd.DataFrame:
        q = ("SELECT r.id, r.kind, r.nightly_id, r.study, r.parts, r.started, r.ended, r.status, r.commit_id, "
             "r.dirty, r.n_cases, r.n_done, r.n_failed, r.n_cached, r.wall_s, "
             "(SELECT COUNT(*) FROM checks c WHERE c.run_id = r.id AND c.status = 'pass') AS n_pass, "
             "(SELECT COUNT(*) FROM checks c WHERE c.run_id = r.id) AS n_checks, "
             "(SELECT COUNT(*) FROM cases k WHERE k.run_id = r.id AND (k.status = 'refused' OR "
             "(k.status = 'ok' AND COALESCE(k.error, '') != ''))) AS n_refused "
             "FROM runs r WHERE 1 = 1")
        args: list = []
        if study:
            q += " AND r.study = ?"
            args.append(study)
        if kind:
            q += " AND r.kind = ?"
            args.append(kind)
        q += " ORDER BY r.id DESC"
        if limit:
            q += f" LIMIT {int(limit)}"
        runs = self._query(q, self.db, params=args)
        dead = self._crashed.get("runs", set())
        if dead and len(runs):
            runs.loc[runs["id"].isin(dead) & (runs["status"] == "running"), "status"] = "crashed"
        return runs

    def run(self, run_id: int) -> dict:
        row = (self.db.execute("SELECT * FROM runs WHERE id = ?", (run_id,)).fetchone()
               if 0 < run_id <= MAX_RUN_ID else None)
        if row is None:
            last = self.db.execute("SELECT MAX(id) FROM runs").fetchone()[0]
            raise ConfigError(f"{self.path}: no run {run_id}" + (f" (runs 1 to {last})" if last else " (empty)"))
        d = dict(row)
        if d["status"] == "running" and d["id"] in self._crashed.get("runs", ()):
            d["status"] = "crashed"
        for key in ("parts", "environment"):
            try:
                d[key] = json.loads(d[key])
            except (TypeError, ValueError) as exc:
                raise OutputError(f"{self.path}: run {run_id}: its {key!r} is not JSON ({exc}); the history was "
                                  f"edited or damaged") from None
        return d

    def cases(self, run_id: int) -> pd.DataFrame:
        return self._query("SELECT * FROM cases WHERE run_id = ? ORDER BY rowid", self.db, params=[run_id])

    def checks(self, run_id: int) -> pd.DataFrame:
        return self._query("SELECT * FROM checks WHERE run_id = ? ORDER BY rowid", self.db, params=[run_id])

    def rows(self, run_id: int) -> pd.DataFrame:
        """The tidy rows of a run (one per metric per case), labels as columns."""
        df = self._query(
            "SELECT r.case_id, c.part, c.seed, r.estimator, r.metric, r.value, r.labels, c.wall_time_s, "
            "c.cached FROM results r JOIN cases c ON c.run_id = r.run_id AND c.case_id = r.case_id "
            "WHERE r.run_id = ? ORDER BY r.rowid", self.db, params=[run_id])
        df["value"] = df["value"].astype(float)
        return df

    def nightlies(self, limit: int | None = None) -> pd.DataFrame:
        q = "SELECT * FROM nightlies ORDER BY id DESC" + (f" LIMIT {int(limit)}" if limit else "")
        return self._query(q, self.db)

    def nightly_runs(self, nightly_id: int) -> dict[str, int]:
        """study -> run id of a nightly (the last run of each study in it)."""
        rows = self.db.execute("SELECT study, MAX(id) FROM runs WHERE nightly_id = ? GROUP BY study",
                               (nightly_id,)).fetchall()
        return {r[0]: int(r[1]) for r in rows}

    def previous_nightly_run(self, study: str, before_nightly: int) -> int | None:
        """The run of ``study`` in the latest finished nightly before ``before_nightly``."""
        row = self.db.execute(
            "SELECT MAX(r.id) FROM runs r JOIN nightlies n ON n.id = r.nightly_id WHERE r.study = ? AND "
            "n.id < ? AND n.status = 'complete' AND r.status = 'ok'", (study, before_nightly)).fetchone()
        return int(row[0]) if row and row[0] is not None else None

    def keys_in_use(self, keep_runs: int) -> set[str]:
        """Cache keys of the last ``keep_runs`` finished runs of every study."""
        keys: set[str] = set()
        studies = [r[0] for r in self.db.execute("SELECT DISTINCT study FROM runs")]
        for s in studies:
            ids = [r[0] for r in self.db.execute("SELECT id FROM runs WHERE study = ? AND status IN "
                                                 "('ok', 'interrupted') ORDER BY id DESC LIMIT ?", (s, keep_runs))]
            for i in ids:
                keys |= {r[0] for r in self.db.execute("SELECT cache_key FROM cases WHERE run_id = ? AND "
                                                       "cache_key IS NOT NULL", (i,))}
        return keys
