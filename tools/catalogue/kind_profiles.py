"""Profiles read from files (``K: {shape: file, path: ...}``): missing, pinned, edited, hostile files."""
from __future__ import annotations

import os

import numpy as np
import pandas as pd

from tools.catalogue import fixtures as fx
from tools.catalogue.core import case


def _study(ws, path, seeds=1, **extra):
    exp = dict(fx.EXPERIMENT, joint={"model": "time_varying", "I": 0.01, "B": 0.5,
                                     "K": {"shape": "file", "path": str(path), **extra}})
    fx.study(ws, parts={"fit": fx.fit_part(seeds=seeds, experiment=exp)}, name="s")


def _with(make, **extra):
    def setup(ws):
        _study(ws, make(ws), **extra)
    return setup


def _args(ws):
    return ["run", ws.path("configs", "s.yaml"), "--out", ws.out, "--quiet"]


def _text(text: str | bytes, name="k.csv"):
    def make(ws):
        p = ws.path(name)
        p.write_bytes(text if isinstance(text, bytes) else text.encode())
        return p
    return make


def good(ws):
    return (fx.profile_csv(ws.path("k.csv")))
kind = "profiles"
case(kind, "missing file", setup=_with(lambda ws: ws.path("nope.csv")), args=_args, names=r"nope\.csv")
case(kind, "wrong sha256", setup=_with(good, sha256="ab" * 32), args=_args, names=r"k\.csv.*SHA|sha")
case(kind, "sha256 not hex", setup=_with(good, sha256="xyz"), args=_args, names=r"sha256|SHA")
case(kind, "makes K negative", setup=_with(lambda ws: fx.profile_csv(ws.path("k.csv"), low=-5)), args=_args,
     names=r"\bK\b")
case(kind, "bad header", setup=_with(_text("t,v\n0,1\n10,2\n")), args=_args, names=r"k\.csv.*header")
case(kind, "non-numeric value", setup=_with(_text("time,value\n0,1\n5,abc\n10,2\n")), args=_args,
     names=r"k\.csv.*line 3")
case(kind, "latin-1 comment", setup=_with(_text("# Müller\ntime,value\n0,50\n10,50\n".encode("latin-1"))),
     args=_args, names=r"k\.csv.*(UTF-8|encod)")
case(kind, "UTF-16 file", setup=_with(_text("time,value\n0,50\n10,50\n".encode("utf-16"))), args=_args,
     names=r"k\.csv")
case(kind, "empty file", setup=_with(_text("")), args=_args, names=r"k\.csv.*empty")
case(kind, "one row", setup=_with(_text("time,value\n0,50\n")), args=_args, names=r"k\.csv.*2 rows")
case(kind, "times not increasing", setup=_with(_text("time,value\n0,50\n5,50\n5,60\n10,50\n")), args=_args,
     names=r"k\.csv.*increase")
case(kind, "NaN value", setup=_with(_text("time,value\n0,50\n5,nan\n10,50\n")), args=_args, names=r"k\.csv.*finite")
case(kind, "three columns", setup=_with(_text("time,value\n0,50,1\n10,50,1\n")), args=_args, names=r"k\.csv.*fields")
case(kind, "a folder", setup=_with(lambda ws: (ws.path("k.csv").mkdir(), ws.path("k.csv"))[1]), args=_args,
     names=r"k\.csv")
case(kind, "unsupported suffix", setup=_with(_text("time,value\n0,1\n", name="k.txt")), args=_args,
     names=r"k\.txt")
case(kind, "symlink to /dev/zero (.csv)", timeout=40, args=_args, names=r"k\.csv.*(regular|not a file|device)",
     setup=_with(lambda ws: (os.symlink("/dev/zero", ws.path("k.csv")), ws.path("k.csv"))[1]))
case(kind, "symlink to /dev/zero (.npy)", timeout=40, args=_args, names=r"k\.npy.*(regular|not a file|device)",
     setup=_with(lambda ws: (os.symlink("/dev/zero", ws.path("k.npy")), ws.path("k.npy"))[1]))
case(kind, "a FIFO", timeout=40, args=_args, names=r"k\.csv.*(regular|not a file|FIFO|pipe)",
     setup=_with(lambda ws: (os.mkfifo(ws.path("k.csv")), ws.path("k.csv"))[1]))
case(kind, "a FIFO with sha256", timeout=40, args=_args, names=r"k\.csv.*(regular|not a file|FIFO|pipe)",
     setup=_with(lambda ws: (os.mkfifo(ws.path("k.csv")), ws.path("k.csv"))[1], sha256="ab" * 32))


def _big_csv(ws):
    p = ws.path("k.csv")
    with open(p, "w") as f:
        f.write("time,value\n")
        chunk = 1_000_000
        for i in range(10):
            t = np.arange(i * chunk, (i + 1) * chunk) * 1e-6
            f.write("\n".join(f"{x:.6f},50" for x in t) + "\n")
    return p


case(kind, "CSV of 10^7 rows", timeout=90, setup=_with(_big_csv), args=_args, names=r"k\.csv.*(rows|large|limit|MB)")
case(kind, "npy of object dtype", args=_args, names=r"k\.npy",
     setup=_with(lambda ws: (np.save(ws.path("k.npy"), np.array([[0, "a"], [1, "b"]], dtype=object),
                                     allow_pickle=True), ws.path("k.npy"))[1]))
case(kind, "npy of wrong shape", args=_args, names=r"k\.npy.*shape",
     setup=_with(lambda ws: (np.save(ws.path("k.npy"), np.zeros(5)), ws.path("k.npy"))[1]))
case(kind, "npy truncated", args=_args, names=r"k\.npy",
     setup=_with(lambda ws: (np.save(ws.path("k.npy"), np.zeros((50, 2))),
                             ws.path("k.npy").write_bytes(ws.path("k.npy").read_bytes()[:100]), ws.path("k.npy"))[2]))
case(kind, "ends before the record (every case fails)", expect="fail", names=r"failed",
     setup=_with(lambda ws: fx.profile_csv(ws.path("k.csv"), t_end=2.0)), args=_args)


def _edit_rerun(ws):
    p = fx.profile_csv(ws.path("k.csv"), low=40, high=40)
    _study(ws, p)
    first = ws.jb(*_args(ws), check=True)
    fx.profile_csv(ws.path("k.csv"), low=80, high=80)
    second = ws.jb(*_args(ws))
    second.first = first
    return second


def _recomputed(ws, o):
    if "(0 from cache" not in o.stdout:
        return "the edited profile was served from the cache: " + o.stdout.splitlines()[0]
    k = pd.read_csv(ws.out / "cat" / "cases.csv")
    k = k[k["metric"] == "K"]["value"].median()
    return None if k > 60 else f"K = {k:.1f} after the profile changed from 40 to 80"


case(kind, "edited CSV is recomputed, not served from the cache", expect="ok", driver=_edit_rerun,
     check=_recomputed, timeout=200)


def _touch_rerun(ws):
    p = fx.profile_csv(ws.path("k.csv"))
    _study(ws, p)
    ws.jb(*_args(ws), check=True)
    os.utime(p, (1, 1))                       # same contents, another time stamp
    return ws.jb(*_args(ws))


case(kind, "a touched but unchanged CSV is served from the cache", expect="ok", driver=_touch_rerun,
     check=lambda ws, o: None if "(1 from cache" in o.stdout else "an unchanged profile was recomputed",
     timeout=200)
