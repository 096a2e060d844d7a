"""Read-only and full disks: one line, and the outputs of the last good run intact (or a complete new set)."""
from __future__ import annotations

from tools.catalogue import fixtures as fx
from tools.catalogue.core import case

SPACE = r"(No space|space left|disk is full|full)"


def _args(ws, out=None):
    return ["run", ws.path("configs", "s.yaml"), "--out", out or ws.out, "--quiet"]


def _old_then(size_kb, free_kb, change=True, cached=False):
    """A good run into out/, then a second run (other seeds) on a tmpfs seeded with it, ``free_kb`` left."""
    def driver(ws):
        fx.study(ws, name="s", edit=lambda d: d["parts"]["fit"].update(seeds=2))
        ws.jb(*_args(ws), check=True)
        if change:
            fx.study(ws, name="s", edit=lambda d: d["parts"]["fit"].update(seeds=3))
        if not cached:
            ws.jb("run", ws.path("configs", "s.yaml"), "--out", ws.path("scratch"), "--quiet", "--no-cache")
        mnt = ws.path("mnt")
        o = ws.jb(*_args(ws, mnt), prefix=fx.tmpfs_prefix(mnt, size_kb, seed=ws.out, free_kb=free_kb,
                                                           after=ws.path("after")), timeout=240)
        return o
    return driver


def _set_kept(ws, o):
    """The study's outputs after the run: the old set (the run failed) or a complete new one (it succeeded)."""
    old, new = fx.snapshot(ws.out / "cat"), fx.snapshot(ws.path("after", "cat"))
    if o.rc == 0:
        missing = sorted(set(old) - set(new))
        return f"exit 0 but the set is partial: {', '.join(missing)} missing" if missing else None
    if new != old:
        changed = sorted(k for k in set(old) | set(new) if old.get(k) != new.get(k))
        return f"the failed run changed {', '.join(changed[:6])} of the last good set"
    return None


kind = "disk"
for free in (0, 8, 30, 80, 200, 500):
    case(kind, f"full disk, {free} KB free after the last good run", expect="any", names=SPACE,
         driver=_old_then(60_000, free), keep=_set_kept, needs=fx.need_unshare, timeout=400)
case(kind, "full disk while only the outputs are written (cases cached)", expect="any", names=SPACE,
     driver=_old_then(60_000, 30, change=False, cached=True), keep=_set_kept, needs=fx.need_unshare, timeout=400)


def _fresh(size_kb):
    def driver(ws):
        fx.study(ws, name="s")
        mnt = ws.path("mnt")
        return ws.jb(*_args(ws, mnt), prefix=fx.tmpfs_prefix(mnt, size_kb, after=ws.path("after")), timeout=240)
    return driver


for size in (4, 16, 64):
    case(kind, f"a {size} KB disk from the start", expect="any", names=SPACE + "|cannot write", driver=_fresh(size),
         needs=fx.need_unshare, timeout=300)


def _ro(sub):
    def driver(ws):
        fx.study(ws, name="s")
        ws.jb(*_args(ws), check=True)
        folder = ws.out if sub is None else ws.out / sub
        fx.study(ws, name="s", edit=lambda d: d["parts"]["fit"].update(seeds=3))
        return ws.jb(*_args(ws), prefix=fx.readonly_prefix(folder))
    return driver


for sub, name in [(None, "results folder"), ("cat", "study folder"), ("cache", "cache folder")]:
    case(kind, f"read-only {name}", driver=_ro(sub), names=r"(read-only|cannot write)", needs=fx.need_unshare,
         timeout=200)


def _estimate_full(free_kb):
    def driver(ws):
        import shutil

        fx.recording_csv(ws.path("rec.csv"))
        mnt = ws.path("mnt")
        mnt.mkdir()
        args = ["estimate", "-e", "ibk_spectral", "-i", ws.path("rec.csv"), "-o", mnt / "est.csv",
                "--plot", mnt / "est.png"]
        ws.jb(*args, check=True)                          # the last good set
        shutil.copytree(mnt, ws.path("old"))
        fx.recording_csv(ws.path("rec.csv"), seed=3)      # new data: every output would change
        return ws.jb(*args, prefix=fx.tmpfs_prefix(mnt, 20_000, seed=ws.path("old"), free_kb=free_kb,
                                                    after=ws.path("after")))
    return driver


def _estimate_kept(ws, o):
    old, new = fx.snapshot(ws.path("old")), fx.snapshot(ws.path("after"))
    if o.rc == 0:
        missing = sorted(set(old) - set(new))
        return f"exit 0 but {', '.join(missing)} missing" if missing else None
    if new != old:
        return "the failed estimate changed " + ", ".join(sorted(k for k in set(old) | set(new)
                                                                 if old.get(k) != new.get(k)))
    return None


for free in (0, 40, 150):
    case(kind, f"estimate on a full disk, {free} KB free", expect="any", names=SPACE, driver=_estimate_full(free),
         keep=_estimate_kept, needs=fx.need_unshare, timeout=300)
