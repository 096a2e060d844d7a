"""``jointbench nightly``: false alarms with nothing changed, its config's defaults and errors."""
from __future__ import annotations

import sqlite3
from pathlib import Path

import yaml

from tools.catalogue import fixtures as fx
from tools.catalogue.core import case

REPO = Path(__file__).resolve().parents[2]


def _config(ws, studies, omit_cache=False, thresholds=None):
    shipped = yaml.safe_load((REPO / "configs" / "nightly.yaml").read_text())
    data = {"studies": [str(s) for s in studies], "thresholds": thresholds or shipped["thresholds"],
            "timing": shipped.get("timing", {})}
    if not omit_cache:
        data["use_cache"] = shipped.get("use_cache", False)
    ws.path("nightly.yaml").write_text(yaml.safe_dump(data, sort_keys=False))
    return ws.path("nightly.yaml")


def _grid_study(ws):
    part = fx.grid_part(estimator=["ibk_spectral", "irf2_ls"])
    return fx.study(ws, parts={"grid": part}, name="g")


def _twice(omit_cache=False):
    def driver(ws):
        cfg = _config(ws, [_grid_study(ws)], omit_cache=omit_cache)
        ws.jb("nightly", "--config", cfg, "--out", ws.out, "--quiet", timeout=600, check=True)
        return ws.jb("nightly", "--config", cfg, "--out", ws.out, "--quiet", timeout=600)
    return driver


def _no_false_alarm(ws, o):
    return None if o.rc == 0 and "regression" not in o.stdout.splitlines()[0] else \
        "a regression with nothing changed: " + " ".join(o.stdout.split())[:200]


def _recomputed(ws, o):
    with sqlite3.connect(ws.out / "history.sqlite") as db:
        cached = db.execute("SELECT SUM(n_cached) FROM runs WHERE kind = 'nightly'").fetchone()[0]
    return None if not cached else f"{cached} case(s) of the nightlies came from the cache (use_cache omitted)"


kind = "nightly"
case(kind, "nothing changed on a grid study: no regression", expect="ok", driver=_twice(), check=_no_false_alarm,
     timeout=1300, judge_any_exit=True)
case(kind, "config without use_cache recomputes", expect="ok", driver=_twice(omit_cache=True), check=_recomputed,
     timeout=1300)
case(kind, "unknown key", names=r"n\.yaml.*unknwn",
     setup=lambda ws: ws.path("n.yaml").write_text("studies: all\nunknwn: 1\nthresholds: [{metric: '*', abs: 1}]\n"),
     args=lambda ws: ["nightly", "--config", ws.path("n.yaml"), "--out", ws.out])
case(kind, "config latin-1", names=r"n\.yaml",
     setup=lambda ws: ws.path("n.yaml").write_bytes("# Müller\nstudies: all\n".encode("latin-1")),
     args=lambda ws: ["nightly", "--config", ws.path("n.yaml"), "--out", ws.out])
case(kind, "threshold NaN", names=r"abs", args=lambda ws: ["nightly", "--config", ws.path("n.yaml"), "--out", ws.out],
     setup=lambda ws: ws.path("n.yaml").write_text("studies: all\nthresholds: [{metric: '*', abs: .nan}]\n"))
case(kind, "unknown study", names=r"nope", expect="error",
     setup=lambda ws: _config(ws, ["nope"]), args=lambda ws: ["nightly", "--config", ws.path("nightly.yaml"),
                                                           "--out", ws.out, "--quiet"])
case(kind, "config missing", names=r"nope\.yaml", args=lambda ws: ["nightly", "--config", ws.path("nope.yaml")])
