"""The catalogue's machinery: a case, its workspace, running it as a subprocess and classifying the outcome.

A case is a careless, hostile or unlucky use of ``jointbench`` (a bad input, a lost scheduler, a full disk):
``setup`` prepares a fresh folder, ``args`` (or ``driver``) runs the command in its own process with a timeout,
and the outcome is classified:

- ``clean``: what a user should see: an error case exits non-zero with one line that names the thing
  (``names``, a regular expression), or with several when a config file has several errors (the parser
  reports every error of a file at once, one per line): then every line names that file and one names the
  thing (:func:`clean_error`); an ``ok`` case exits 0 and its ``check`` holds; a ``fail`` case (cases that
  fail at run time) exits non-zero and says how many failed;
- ``unclear``: non-zero but several lines that are not all one config file's errors (a line that does not
  name the file), or the wrong thing named (or an ``ok`` case refused);
- ``traceback``: a Python traceback reached the user;
- ``hang``: no answer within the timeout;
- ``silent wrong``: exit 0 where it must not, or a wrong result (the ``check`` failed);
- ``outputs lost``: a run that failed left a partial or mixed set of outputs (the ``keep`` check failed).

Cases are kept apart from the tests (``make catalogue``, never ``make test``) so that they stay an
independent measure of the product.
"""
from __future__ import annotations

import dataclasses
import os
import re
import shutil
import signal
import subprocess
import tempfile
import time
from pathlib import Path
from typing import Callable

CLASSES = ("clean", "unclear", "traceback", "hang", "silent wrong", "outputs lost")
#: informational stderr lines that are not part of an error message (the grid's time estimate)
INFO = re.compile(r"^jointbench: (?!error:).*(estimated \d+ CPU-minutes|lock acquired)")
#: what the command line puts before an error message (on its first line only)
ERROR_PREFIX = re.compile(r"^jointbench: error: ")
#: the config file a line of a config error names, at its start: ``<path>.yaml: <where>: <what>``
CONFIG_FILE = re.compile(r"^(?P<file>\S.*?\.ya?ml): ")


@dataclasses.dataclass
class Outcome:
    rc: int | None
    stdout: str
    stderr: str
    seconds: float
    timed_out: bool = False
    problem: str = ""          # set by a driver or a check: what went wrong
    lost: str = ""             # set by a keep check: outputs lost or mixed
    forced: str = ""           # a driver's own verdict (e.g. "hang" for a wait without a word)


@dataclasses.dataclass
class Case:
    kind: str
    name: str
    expect: str = "error"                      # error | ok | fail | any (0, or a clean error)
    names: str = ""                            # regex the one-line error must match (error, fail)
    args: Callable | list | None = None        # jointbench arguments (list, or ws -> list)
    setup: Callable | None = None              # ws -> None
    driver: Callable | None = None             # ws -> Outcome (instead of args)
    check: Callable | None = None              # (ws, outcome) -> problem text or None ("silent wrong")
    keep: Callable | None = None               # (ws, outcome) -> problem text or None ("outputs lost")
    timeout: float = 90.0
    prefix: Callable | list | None = None      # a command prefix (unshare ...), or ws -> list
    needs: Callable | None = None              # () -> reason to skip, or None
    judge_any_exit: bool = False               # an ok case whose check judges a non-zero exit too (a false alarm)

    @property
    def id(self) -> str:
        return f"{self.kind}/{self.name}"


CASES: list[Case] = []


def case(kind: str, name: str, **kw) -> Case:
    c = Case(kind, name, **kw)
    if any(x.id == c.id for x in CASES):
        raise ValueError(f"case {c.id} defined twice")
    CASES.append(c)
    return c


class Workspace:
    """A fresh folder for one case and the jointbench command under test (``python -m jointbench``)."""

    def __init__(self, root: Path, python: str):
        self.dir = Path(root)
        self.python = python
        self.out = self.dir / "out"
        self.procs: list[subprocess.Popen] = []

    def path(self, *parts) -> Path:
        return self.dir.joinpath(*parts)

    def env(self, extra: dict | None = None) -> dict:
        env = dict(os.environ)
        env.update({"PYTHONUNBUFFERED": "1", "OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1",
                    "MPLBACKEND": "Agg"})
        env.update(extra or {})
        return env

    def command(self, args, prefix=None) -> list[str]:
        return [*(prefix or []), self.python, "-m", "jointbench", *map(str, args)]

    def jb(self, *args, timeout: float = 300, prefix=None, env: dict | None = None, check: bool = False) -> Outcome:
        """Run jointbench to completion (setup steps and simple cases)."""
        t0 = time.monotonic()
        p = subprocess.Popen(self.command(args, prefix), cwd=self.dir, stdout=subprocess.PIPE,
                             stderr=subprocess.PIPE, text=True, env=self.env(env), start_new_session=True,
                             errors="replace")
        try:
            out, err = p.communicate(timeout=timeout)
            res = Outcome(p.returncode, out, err, time.monotonic() - t0)
        except subprocess.TimeoutExpired:
            kill_group(p)
            out, err = p.communicate()
            res = Outcome(None, out, err, time.monotonic() - t0, timed_out=True)
        if check and res.rc != 0:
            raise RuntimeError(f"setup step jointbench {' '.join(map(str, args))} failed ({res.rc}): "
                               f"{res.stderr.strip()[-600:]}")
        return res

    def start(self, args, prefix=None, env: dict | None = None, log: str = "run.log") -> subprocess.Popen:
        f = open(self.path(log), "w")
        p = subprocess.Popen(self.command(args, prefix), cwd=self.dir, stdout=f, stderr=subprocess.STDOUT,
                             env=self.env(env), start_new_session=True)
        self.procs.append(p)
        return p

    def spawn(self, argv: list[str], log: str, env: dict | None = None) -> subprocess.Popen:
        """Any helper process (a Dask scheduler, a server), stopped when the case ends."""
        f = open(self.path(log), "w")
        p = subprocess.Popen(argv, cwd=self.dir, stdout=f, stderr=subprocess.STDOUT, env=self.env(env),
                             start_new_session=True)
        self.procs.append(p)
        return p

    def close(self) -> None:
        for p in self.procs:
            if p.poll() is None:
                kill_group(p)


def kill_group(p: subprocess.Popen) -> None:
    try:
        os.killpg(p.pid, signal.SIGKILL)
    except (ProcessLookupError, PermissionError):
        pass
    try:
        p.wait(10)
    except subprocess.TimeoutExpired:
        pass


def message_lines(text: str) -> list[str]:
    return [ln for ln in (x.strip() for x in text.splitlines()) if ln and not INFO.match(ln)]


def classify(c: Case, o: Outcome) -> str:
    if o.forced:
        return o.forced
    if o.timed_out:
        return "hang"
    if "Traceback (most recent call last)" in o.stderr or "Traceback (most recent call last)" in o.stdout:
        return "traceback"
    if o.lost:
        return "outputs lost"
    if c.expect == "any" and o.rc == 0:            # either outcome may be right (a disk that was not full)
        return "silent wrong" if o.problem else "clean"
    if c.expect == "ok":
        if o.rc != 0 and not c.judge_any_exit:
            return "unclear"                   # refused what it should have done, but said so
        return "silent wrong" if o.problem else "clean"
    if o.rc == 0:
        return "silent wrong"
    if o.problem:
        return "unclear"
    lines = message_lines(o.stderr)
    if c.expect == "fail":
        text = o.stdout + o.stderr
        return "clean" if re.search(r"\d+ (case\(s\) |of \d+ cases )?failed", text) and re.search(c.names, text) \
            else "unclear"
    return "clean" if clean_error(c.names, lines) else "unclear"


def clean_error(names: str, lines: list[str]) -> bool:
    """Whether the lines of an error message are what a user should see: one line that names the thing
    (``names``, a regular expression), or every error of one config file, one per line (:func:`each_names_one_file`),
    one of them naming the thing."""
    if len(lines) == 1:
        return bool(re.search(names, lines[0], re.I))
    return each_names_one_file(lines) and any(re.search(names, ln, re.I) for ln in lines)


def each_names_one_file(lines: list[str]) -> bool:
    """Whether several lines are errors of one config file: each starts with the path of the file the
    first names (``<path>.yaml: ...``, the first after the command line's ``jointbench: error: ``). A line
    that does not name the file (a hint, a warning, an error that lost its origin) makes them unclear."""
    if len(lines) < 2:
        return False
    first = CONFIG_FILE.match(ERROR_PREFIX.sub("", lines[0], count=1))
    if first is None:
        return False
    named = first.group("file") + ": "
    return all(ERROR_PREFIX.sub("", ln, count=1).startswith(named) for ln in lines)


def run_one(c: Case, python: str, keep_dir: Path | None = None) -> dict:
    root = Path(tempfile.mkdtemp(prefix=f"cat-{c.kind}-"))
    ws = Workspace(root, python)
    t0 = time.monotonic()
    try:
        reason = c.needs() if c.needs else None
        if reason:
            return {"kind": c.kind, "case": c.name, "class": "skipped", "rc": "", "seconds": 0.0, "message": reason}
        if c.setup:
            c.setup(ws)
        if c.driver:
            o = c.driver(ws)
        else:
            args = c.args(ws) if callable(c.args) else list(c.args or [])
            prefix = c.prefix(ws) if callable(c.prefix) else c.prefix
            o = ws.jb(*args, timeout=c.timeout, prefix=prefix)
        if not o.timed_out:
            if c.check and not o.problem:
                try:
                    o.problem = c.check(ws, o) or ""
                except Exception:  # noqa: BLE001 - nothing to check (e.g. no outputs after a refusal)
                    o.problem = "" if o.rc != 0 else "its outputs cannot be checked"
            if c.keep:
                o.lost = c.keep(ws, o) or ""
        cls = classify(c, o)
        lines = message_lines(o.stderr)
        msg = o.problem or o.lost or (lines[-1] if lines else (o.stdout.strip().splitlines() or [""])[-1])
        return {"kind": c.kind, "case": c.name, "class": cls, "rc": "" if o.rc is None else o.rc,
                "seconds": round(time.monotonic() - t0, 1), "message": msg[:300],
                "stderr_lines": len(lines)}
    except Exception as exc:  # noqa: BLE001 - a broken case is reported, the catalogue goes on
        return {"kind": c.kind, "case": c.name, "class": "broken case", "rc": "", "seconds":
                round(time.monotonic() - t0, 1), "message": f"{type(exc).__name__}: {exc}"[:300]}
    finally:
        ws.close()
        if keep_dir is None:
            shutil.rmtree(root, ignore_errors=True)
            subprocess.run(["rm", "-rf", str(root)], capture_output=True)
