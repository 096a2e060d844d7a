"""The run history: corrupt, edited, locked and absent histories; ``history`` and ``diff`` arguments."""
from __future__ import annotations

import sqlite3
import time

from tools.catalogue import fixtures as fx
from tools.catalogue.core import Outcome, case


def _args(ws):
    return ["run", ws.path("configs", "s.yaml"), "--out", ws.out, "--quiet"]


def _history(ws, runs=1):
    fx.study(ws, name="s")
    for _ in range(runs):
        ws.jb(*_args(ws), check=True)


def _edit(sql, runs=1):
    def setup(ws):
        _history(ws, runs)
        with sqlite3.connect(ws.out / "history.sqlite") as db:
            for stmt in ([sql] if isinstance(sql, str) else sql):
                db.execute(stmt)
    return setup


def H(*more):
    return ((lambda ws: ["history", *more, "--out", ws.out]))
kind = "history"
case(kind, "a run's parts not JSON", setup=_edit("UPDATE runs SET parts = 'not json'"), args=H("1"),
     names=r"history\.sqlite")
case(kind, "a run's environment not JSON", setup=_edit("UPDATE runs SET environment = '{'"), args=H("1"),
     names=r"history\.sqlite")
case(kind, "schema version 99", setup=_edit("UPDATE meta SET value = '99' WHERE key = 'schema_version'"), args=H(),
     names=r"schema version")
case(kind, "schema version not a number", setup=_edit("UPDATE meta SET value = 'two' WHERE key = 'schema_version'"),
     args=H(), names=r"schema version")
case(kind, "schema version 99, run", setup=_edit("UPDATE meta SET value = '99' WHERE key = 'schema_version'"),
     args=_args, names=r"schema version")
case(kind, "runs table dropped", setup=_edit(["DROP TABLE results", "DROP TABLE checks", "DROP TABLE cases",
                                              "DROP TABLE runs"]), args=H(), names=r"history\.sqlite")
case(kind, "a column missing", setup=_edit("ALTER TABLE runs DROP COLUMN wall_s"), args=H(), names=r"history\.sqlite")
case(kind, "history 10^30", setup=_history, args=H("1" + "0" * 30), names=r"run|10{30}")
case(kind, "history -1", setup=_history, args=H("-1"), names=r"run|-1")
case(kind, "history 99 (no such run)", setup=_history, args=H("99"), names=r"no run 99")
case(kind, "history abc", setup=_history, args=H("abc"), names=r"abc")
case(kind, "history --limit 0", setup=_history, args=H("--limit", "0"), names=r"limit")
case(kind, "history without a history", args=H(), names=r"no run history")
case(kind, "history file is garbage", setup=lambda ws: (ws.out.mkdir(), (ws.out / "history.sqlite").write_bytes(b"x" * 5000)),
     args=H(), names=r"history\.sqlite")
case(kind, "history file is garbage, run", args=_args, names=r"history\.sqlite",
     setup=lambda ws: (fx.study(ws, name="s"), ws.out.mkdir(), (ws.out / "history.sqlite").write_bytes(b"x" * 5000)))
case(kind, "history file truncated", names=r"history\.sqlite", args=H(),
     setup=lambda ws: (_history(ws), (ws.out / "history.sqlite").write_bytes((ws.out / "history.sqlite").read_bytes()[:3000]),
                       [p.unlink() for p in ws.out.glob("history.sqlite-*")]))
case(kind, "history file is a folder", setup=lambda ws: (ws.out.mkdir(), (ws.out / "history.sqlite").mkdir()),
     args=H(), names=r"history\.sqlite")
case(kind, "history is a symlink to /dev/zero", timeout=30, names=r"history\.sqlite",
     setup=lambda ws: (ws.out.mkdir(), (ws.out / "history.sqlite").symlink_to("/dev/zero")), args=H())
case(kind, "diff of two studies", expect="error", names=r"different studies",
     setup=lambda ws: (_history(ws), fx.study(ws, name="t", study_id="other"),
                       ws.jb("run", ws.path("configs", "t.yaml"), "--out", ws.out, "--quiet", check=True)),
     args=lambda ws: ["diff", "1", "2", "--out", ws.out])
case(kind, "diff with a missing run", setup=_history, args=lambda ws: ["diff", "1", "7", "--out", ws.out],
     names=r"no run 7")
case(kind, "diff 10^30", setup=_history, args=lambda ws: ["diff", "1", "1" + "0" * 30, "--out", ws.out],
     names=r"run|10{30}")


def _unrecorded(ws):
    _history(ws, runs=2)
    with sqlite3.connect(ws.out / "history.sqlite") as db:
        db.execute("UPDATE checks SET evidence = NULL")                  # runs recorded before evidence was
        db.execute("UPDATE checks SET status = 'miss' WHERE run_id = 1")
    return ws.jb("diff", "1", "2", "--out", ws.out)


case(kind, "diff labels checks of old runs 'unrecorded'", expect="ok", driver=_unrecorded,
     check=lambda ws, o: None if "unrecorded" in o.stdout else "an old run's check without evidence is not "
     "shown as unrecorded", timeout=120)


def _locked(command):
    def driver(ws):
        _history(ws)
        db = sqlite3.connect(ws.out / "history.sqlite", isolation_level=None)
        db.execute("BEGIN IMMEDIATE")            # another process writing (a long transaction)
        t0 = time.monotonic()
        try:
            if command == "history":
                o = ws.jb("history", "--out", ws.out, timeout=90)
                if o.seconds > 15:
                    o.forced = "hang"
                    o.problem = f"the reader waited {o.seconds:.0f} s behind a writer's lock"
                elif o.rc != 0:
                    o.problem = "the reader failed: " + o.stderr.strip()[-200:]
                return o
            p = ws.start(_args(ws), log="run.log")
            said = ""
            while time.monotonic() - t0 < 40 and p.poll() is None:
                text = ws.path("run.log").read_text()
                if "wait" in text.lower() and "history" in text.lower():
                    said = text
                    break
                time.sleep(0.5)
            db.execute("ROLLBACK")
            p.wait(120)
            text = ws.path("run.log").read_text()
            o = Outcome(p.returncode, "", text, time.monotonic() - t0)
            if not said:
                o.forced, o.problem = ("hang", "waited without a word for the history lock") \
                    if p.returncode == 0 or time.monotonic() - t0 > 40 else ("", "")
            return o
        finally:
            db.close()
    return driver


case(kind, "locked history: history (a reader)", expect="ok", driver=_locked("history"), timeout=150)
case(kind, "locked history: run says it waits", expect="ok", driver=_locked("run"), timeout=200)
