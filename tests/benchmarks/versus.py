"""The times a user waits, this commit against an earlier one, measured side by side (interleaved).

    python -m tests.benchmarks.versus BEFORE [--pairs N] [--what reproduce,estimate,test]

Issue 34's rule for speed-only code: a mechanism stays only where removing it costs more than 10 % of a
time a user waits. This measures those times for two commits, ``BEFORE`` and ``HEAD``, each in a fresh
clone with its own ``.venv`` (made first, not timed), alternately (before, after, before, after, ...) so
that both see the same load on the shared machine:

- ``reproduce``: ``make reproduce`` with an empty cache (``XDG_CACHE_HOME`` and ``MPLCONFIGDIR`` new
  folders), the results folder reset to the clone's committed one and every ``__pycache__`` of the clone
  (where numba caches the compiled loops) removed first: a newcomer's first run;
- ``estimate``: ``jointbench estimate`` on a one-minute record (60 s at 1 kHz, simulated once by HEAD's
  API with a fixed seed) with ``fsewls``, and on an ensemble of ten one-minute records at 100 Hz with
  ``ensemble_irf`` (the two fits whose compiled loops were removed);
- ``matrix``: ``make matrix`` (every estimator on every scenario) with an empty cache, as ``reproduce``;
- ``test``: ``make test``.

Wall and CPU seconds (the children's, from ``wait4``) are appended to ``results/speed_versus.csv``
(committed: results/benchmarks.md shows its medians and ratios, :func:`render`); a command that fails
is recorded with its exit status, never as a time.
"""
from __future__ import annotations

import argparse
import csv
import datetime
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
TABLE = REPO / "results" / "speed_versus.csv"
FIELDS = ["date", "versus", "label", "commit", "command", "pair", "wall_s", "cpu_s", "exit", "load_before", "note"]
WHAT = ("reproduce", "estimate", "matrix", "test")


def _git(*args: str, cwd: Path = REPO) -> str:
    return subprocess.run(["git", *args], cwd=cwd, check=True, capture_output=True, text=True).stdout.strip()


def clone(commit: str, where: Path) -> Path:
    """A fresh clone of ``commit`` at ``where`` with its ``.venv`` made (not timed)."""
    subprocess.run(["git", "clone", "--quiet", "--no-hardlinks", str(REPO), str(where)], check=True)
    subprocess.run(["git", "checkout", "--quiet", commit], cwd=where, check=True)
    subprocess.run(["make", "venv"], cwd=where, check=True, stdout=subprocess.DEVNULL)
    return where


def timed(cmd: list[str], cwd: Path, env: dict) -> tuple[float, float, int]:
    """Wall seconds, CPU seconds of the command and its children, exit status."""
    t0 = time.perf_counter()
    proc = subprocess.Popen(cmd, cwd=cwd, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    _, status, usage = os.wait4(proc.pid, 0)
    proc.returncode = os.waitstatus_to_exitcode(status)
    return time.perf_counter() - t0, usage.ru_utime + usage.ru_stime, proc.returncode


def records(folder: Path, python: Path) -> dict[str, list[Path]]:
    """The records of the ``estimate`` commands, simulated once by HEAD's API (fixed seeds)."""
    folder.mkdir(parents=True, exist_ok=True)
    script = f"""
import numpy as np, pandas as pd
from jointbench import api
def write(path, trial):
    pd.DataFrame({{"time": trial.time, "angle": trial.angle, "torque": trial.torque}}).to_csv(path, index=False)
def elbow(seed, fs):      # 60 s kept of 61 (0.5 s trimmed at each end)
    return api.simulate("matrix:xu1998_elbow", seed=seed, duration=61.0, acquisition={{"fs": fs, "trim": 0.5}})
write("{folder}/elbow_60s_1kHz.csv", elbow(1, 1000.0))
for r in range(10):
    write(f"{folder}/elbow_60s_100Hz_{{r}}.csv", elbow(100 + r, 100.0))
"""
    subprocess.run([str(python), "-c", script], check=True)
    return {"fsewls": [folder / "elbow_60s_1kHz.csv"],
            "ensemble_irf": sorted(folder.glob("elbow_60s_100Hz_*.csv"))}


def commands(what: str, data: dict[str, list[Path]] | None) -> list[tuple[str, list[str], bool]]:
    """(name, argv relative to the clone, fresh cache) of one kind of wait."""
    if what == "reproduce":
        return [("make reproduce (fresh clone, empty cache)", ["make", "reproduce"], True)]
    if what == "matrix":
        return [("make matrix (empty cache)", ["make", "matrix"], True)]
    if what == "test":
        return [("make test", ["make", "test"], False)]
    out = [("jointbench estimate fsewls, one 60 s record at 1 kHz",
            [".venv/bin/jointbench", "estimate", "-e", "fsewls", "-i", str(data["fsewls"][0]), "-o", "OUT.csv"],
            False)]
    ens = [a for f in data["ensemble_irf"] for a in ("-i", str(f))]
    out.append(("jointbench estimate ensemble_irf, 10 records of 60 s at 100 Hz",
                [".venv/bin/jointbench", "estimate", "-e", "ensemble_irf", "--ensemble", *ens, "-o", "OUT.csv"],
                False))
    return out


def run_pairs(before: str, pairs: int, what: list[str], note: str = "") -> list[dict]:
    rows = []
    with tempfile.TemporaryDirectory(prefix="jointbench-versus-") as tmp:
        tmp = Path(tmp)
        clones = {"before": clone(before, tmp / "before"), "after": clone("HEAD", tmp / "after")}
        commits = {k: _git("rev-parse", "--short", "HEAD", cwd=c) for k, c in clones.items()}
        data = records(tmp / "records", clones["after"] / ".venv/bin/python") if "estimate" in what else None
        for kind in what:
            for name, argv, fresh in commands(kind, data):
                for i in range(pairs):
                    for label in ("before", "after"):
                        where = clones[label]
                        env = {**os.environ}
                        if fresh:
                            subprocess.run(["git", "checkout", "--quiet", "--", "results"], cwd=where, check=True)
                            subprocess.run(["git", "clean", "-fdqx", "results"], cwd=where, check=True)
                            for pyc in where.glob("[!.]*/**/__pycache__"):     # a fresh clone has none: numba's
                                shutil.rmtree(pyc, ignore_errors=True)       # disk cache lives there too
                            cache = tmp / f"cache-{label}-{i}"
                            shutil.rmtree(cache, ignore_errors=True)
                            env.update(XDG_CACHE_HOME=str(cache), MPLCONFIGDIR=str(cache / "matplotlib"))
                        load = os.getloadavg()[0]
                        wall, cpu, code = timed(argv, where, env)
                        row = {"date": datetime.datetime.now().isoformat(timespec="seconds"),
                               "versus": f"{commits['before']}..{commits['after']}", "label": label,
                               "commit": commits[label], "command": name, "pair": i, "wall_s": f"{wall:.2f}",
                               "cpu_s": f"{cpu:.2f}", "exit": code, "load_before": f"{load:.2f}", "note": note}
                        rows.append(row)
                        print(f"{name} [{label} {commits[label]}] pair {i}: {wall:.1f} s wall, {cpu:.1f} CPU-s, "
                              f"exit {code}", flush=True)
    return rows


def append(rows: list[dict]) -> None:
    new = not TABLE.is_file()
    with TABLE.open("a", newline="") as f:
        w = csv.DictWriter(f, FIELDS)
        if new:
            w.writeheader()
        w.writerows(rows)


def medians(rows: list[dict]) -> list[dict]:
    """Per command and pair of commits: the medians of the successful runs and the after/before ratios."""
    out = []
    by: dict = {}
    for r in rows:
        by.setdefault((r["versus"], r["command"], r.get("note") or ""), []).append(r)
    for (_, command, note), rs in by.items():
        name = f"{command} ({note})" if note else command
        ok = {lab: [r for r in rs if r["label"] == lab and int(r["exit"]) == 0] for lab in ("before", "after")}
        failed = sum(int(r["exit"]) != 0 for r in rs)
        if not ok["before"] or not ok["after"]:
            out.append({"command": name, "failed": failed})
            continue
        m = {lab: (statistics.median(float(r["wall_s"]) for r in v), statistics.median(float(r["cpu_s"]) for r in v))
             for lab, v in ok.items()}
        out.append({"command": name, "before": ok["before"][0]["commit"], "after": ok["after"][0]["commit"],
                    "n": min(len(ok["before"]), len(ok["after"])), "wall": m["before"][0], "wall_after": m["after"][0],
                    "cpu": m["before"][1], "cpu_after": m["after"][1], "failed": failed})
    return out


def render(rows: list[dict]) -> str:
    """The markdown section of results/benchmarks.md: medians and ratios from the recorded runs."""
    lines = ["## Speed-only code removed (issue 34): the times a user waits, before and after",
             "",
             "Each command run alternately on a fresh clone of the commit before the removals and of the commit "
             "after (`python -m tests.benchmarks.versus`, results/speed_versus.csv); medians of the successful runs. "
             "A mechanism stays only where removing it costs more than 10 % of such a time.",
             "",
             "| command | before | after | runs each | wall s before | wall s after | wall ratio | CPU s before "
             "| CPU s after | CPU ratio | failed runs |",
             "|---|---|---|---|---|---|---|---|---|---|---|"]
    for m in medians(rows):
        if "wall" not in m:
            lines.append(f"| {m['command']} | | | 0 | | | | | | | {m['failed']} |")
            continue
        lines.append(f"| {m['command']} | `{m['before']}` | `{m['after']}` | {m['n']} | {m['wall']:.1f} | "
                     f"{m['wall_after']:.1f} | {m['wall_after'] / m['wall']:.2f} | {m['cpu']:.1f} | "
                     f"{m['cpu_after']:.1f} | {m['cpu_after'] / m['cpu']:.2f} | {m['failed']} |")
    return "\n".join(lines) + "\n"


def read() -> list[dict]:
    if not TABLE.is_file():
        return []
    with TABLE.open(newline="") as f:
        return list(csv.DictReader(f))


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m tests.benchmarks.versus", description=__doc__.split("\n\n")[0])
    ap.add_argument("before", help="the commit to compare HEAD with")
    ap.add_argument("--pairs", type=int, default=3, help="interleaved pairs per command (default 3)")
    ap.add_argument("--what", default="reproduce,estimate", help=f"comma-separated, of {', '.join(WHAT)}")
    ap.add_argument("--note", default="", help="what HEAD is, when it is not the commit on main (a variant)")
    a = ap.parse_args(argv)
    what = [w.strip() for w in a.what.split(",") if w.strip()]
    bad = [w for w in what if w not in WHAT]
    if bad:
        ap.error(f"--what {','.join(bad)}: not one of {', '.join(WHAT)}")
    rows = run_pairs(a.before, a.pairs, what, a.note)
    append(rows)
    print(render(rows))
    return 0 if all(int(r["exit"]) == 0 for r in rows) else 1


if __name__ == "__main__":
    sys.exit(main())
