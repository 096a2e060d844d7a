"""Runs: the exit status when cases fail, cache entries of the wrong type, worker counts."""
from __future__ import annotations

import json
import os
from pathlib import Path

from tools.catalogue import fixtures as fx
from tools.catalogue.core import case


def _failing(ws, seeds=2, fail_all=True, expected=False):
    fx.profile_csv(ws.path("short.csv"), t_end=2.0)
    fx.profile_csv(ws.path("long.csv"), t_end=10.0)
    exp_bad = dict(fx.EXPERIMENT, joint={"model": "time_varying", "I": 0.01, "B": 0.5,
                                         "K": {"shape": "file", "path": str(ws.path("short.csv"))}})
    parts = {"fit": fx.fit_part(seeds=seeds, experiment=None if not fail_all else exp_bad)}
    if not fail_all:
        parts["bad"] = fx.fit_part(seeds=1, experiment=exp_bad)
    edit = (lambda d: d.update(expected_failures=True)) if expected else None
    fx.study(ws, parts=parts, name="s", edit=edit)


def _args(ws):
    return ["run", ws.path("configs", "s.yaml"), "--out", ws.out, "--quiet"]


kind = "runs"
case(kind, "every case fails", expect="fail", names=r"failed", setup=_failing, args=_args)
case(kind, "one case of three fails", expect="fail", names=r"failed",
     setup=lambda ws: _failing(ws, fail_all=False), args=_args)
case(kind, "one case fails, --strict", expect="fail", names=r"failed",
     setup=lambda ws: _failing(ws, fail_all=False), args=lambda ws: _args(ws) + ["--strict"])
case(kind, "failures the study expects", expect="ok", setup=lambda ws: _failing(ws, fail_all=False, expected=True),
     args=_args, check=lambda ws, o: None if "failed" in o.stdout else "the failures were not reported")
case(kind, "every case fails on the process pool", expect="fail", names=r"failed", setup=_failing,
     args=lambda ws: _args(ws) + ["--workers", "2"])


def _entry_edit(mutate):
    def driver(ws):
        fx.study(ws, name="s")
        ws.jb(*_args(ws), check=True)
        entries = sorted((ws.out / "cache").glob("??/*.json"))
        for p in entries:
            mutate(p)
        return ws.jb(*_args(ws))
    return driver


def _rewrite(fn):
    def mutate(p: Path):
        entry = json.loads(p.read_text())
        p.write_text(json.dumps(fn(entry)))
    return mutate


def _sha(obj):
    import hashlib

    from jointbench.benchmarks.harness import fingerprint
    return fingerprint.sha(obj) if hasattr(fingerprint, "sha") else hashlib.sha256(str(obj).encode()).hexdigest()


def _forged_rows(entry):
    entry["result"]["rows"] = 5
    entry["checksum"] = _sha(entry["result"])
    return entry


def _forged_status(entry):
    entry["result"] = ["ok"]
    entry["checksum"] = _sha(entry["result"])
    return entry


def _forged_row_type(entry):
    entry["result"]["rows"] = ["a row"]
    entry["checksum"] = _sha(entry["result"])
    return entry


def recomputed(ws, o):
    return (None if "(0 from cache" in o.stdout else "a damaged entry was served: "
              + (o.stdout.splitlines() or [""])[0])
kind = "cache"
for name, mutate in [("a JSON list", lambda p: p.write_text("[1, 2]")),
                     ("a JSON string", lambda p: p.write_text('"x"')),
                     ("a JSON number", lambda p: p.write_text("3")),
                     ("not JSON", lambda p: p.write_text("{")),
                     ("empty", lambda p: p.write_text("")),
                     ("binary", lambda p: p.write_bytes(b"\xff\xfe\x00")),
                     ("material a string", _rewrite(lambda e: dict(e, material="x"))),
                     ("result a list (checksum forged)", _rewrite(_forged_status)),
                     ("rows a number (checksum forged)", _rewrite(_forged_rows)),
                     ("rows of strings (checksum forged)", _rewrite(_forged_row_type)),
                     ("a symlink to /dev/zero", lambda p: (p.unlink(), os.symlink("/dev/zero", p))),
                     ("a FIFO", lambda p: (p.unlink(), os.mkfifo(p)))]:
    case(kind, f"entry is {name}", expect="ok", driver=_entry_edit(mutate), check=recomputed, timeout=120)


case(kind, "entry is a folder", driver=_entry_edit(lambda p: (p.unlink(), p.mkdir())), names=r"cache|\.json",
     timeout=120)


def _prune_ro(ws):
    fx.study(ws, name="s", edit=lambda d: d["parts"]["fit"]["experiment"].update(duration="5 s"))
    ws.jb(*_args(ws), check=True)                      # entries no later run uses: prune would remove them
    fx.study(ws, name="s", edit=lambda d: d["parts"]["fit"].update(seeds=3))
    ws.jb(*_args(ws), check=True)
    ws.jb(*_args(ws), check=True)
    ws.jb(*_args(ws), check=True)
    return ws.jb("cache", "prune", "--keep-runs", "1", "--out", ws.out, prefix=fx.readonly_prefix(ws.out / "cache"))


case(kind, "cache prune on a read-only cache", driver=_prune_ro, names=r"cache.*(read-only|cannot|writ)",
     needs=fx.need_unshare, timeout=240)
case(kind, "cache prune without a history", args=lambda ws: ["cache", "prune", "--out", ws.out],
     names=r"history")
case(kind, "cache prune --keep-runs 0", args=lambda ws: ["cache", "prune", "--keep-runs", "0", "--out", ws.out],
     names=r"keep-runs")
