"""Tiny study configs (a temporary config folder) and process helpers for the harness tests."""
from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

import yaml

REPO = Path(__file__).resolve().parents[1]


def tiny_study(folder: Path, study: str = "tiny", seeds: int = 4, duration: str = "4 s",
               extra_parts: dict | None = None, estimators: dict | None = None,
               perturbation: dict | None = None) -> Path:
    """A one-part study (second-order joint on a position servo, ibk_spectral) with one check on K.

    One case takes about ``0.004 s`` per simulated second on this machine (``duration: 120 s`` is about
    half a second)."""
    folder.mkdir(parents=True, exist_ok=True)
    pub = folder / f"{study}_published.yaml"
    pub.write_text(yaml.safe_dump({"study": study, "source": "test", "checks": [
        {"id": "T-K", "part": "fit", "description": "K of the fit", "source": "-", "published": 50,
         "low": 45, "high": 55, "select": {"metric": "K", "estimator": "ibk_spectral"},
         "evidence": "sanity", "tolerance_reason": "test band"},
        {"id": "T-vaf", "part": "fit", "description": "torque VAF", "source": "-", "published": 95,
         "low": 90, "high": 100, "select": {"metric": "vaf_torque", "estimator": "ibk_spectral"},
         "evidence": "sanity", "tolerance_reason": "test band"}]}))
    part = {"protocol": "parametric_fit", "description": "second-order fit on filtered noise", "seeds": seeds,
            "experiment": {"joint": {"model": "second_order", "I": 0.01, "B": 0.5, "K": 50},
                           "perturbation": perturbation or {"kind": "filtered_noise", "cutoff": "20 Hz", "order": 2,
                                                            "rms": "0.02 rad"},
                           "apparatus": {"kind": "position_servo", "stiffness": "30000 N.m/rad"},
                           "fs_sim": "2 kHz", "duration": duration, "acquisition": {"fs": "500 Hz"}},
            "estimators": estimators or {"ibk_spectral": {"fmin": "0 Hz", "fmax": "20 Hz", "segment": "2 s",
                                                          "overlap": 0.5}}}
    data = {"study": study, "title": f"Tiny test study {study}", "paper": "none", "published": str(pub),
            "not_reproduced": [], "parts": {"fit": part, **(extra_parts or {})}}
    path = folder / f"{study}.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def study_copy(folder: Path, study: str, edit=None, name: str | None = None) -> Path:
    """A copy of the shipped study ``benchmarks/studies/<study>/study.yaml`` in ``folder`` (as ``name``, default
    ``<study>.yaml``), its published-values path made absolute, edited in place by ``edit(dict)``."""
    shipped = REPO / "benchmarks" / "studies" / study
    data = yaml.safe_load((shipped / "study.yaml").read_text())
    data["published"] = str(shipped / data["published"])
    if edit is not None:
        edit(data)
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / (name or f"{study}.yaml")
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def cli_env() -> dict:
    env = dict(os.environ)
    env["PYTHONUNBUFFERED"] = "1"
    return env


def cli(*args, timeout: float = 300, **kw) -> subprocess.CompletedProcess:
    """``jointbench ARGS`` in a fresh process."""
    return subprocess.run([sys.executable, "-m", "jointbench", *map(str, args)], cwd=REPO,
                          capture_output=True, text=True, timeout=timeout, env=cli_env(), **kw)


def cli_here(*args, timeout: float | None = None) -> subprocess.CompletedProcess:
    """``jointbench ARGS`` in this process (no interpreter start-up): return code, stdout and stderr as
    :func:`cli` gives them, for commands that need no process of their own (no signals, no workers;
    ``timeout`` is accepted for symmetry with :func:`cli` and not enforced)."""
    import contextlib
    import io

    from jointbench.cli import main

    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            code = main([str(a) for a in args])
        except SystemExit as exc:                  # argparse's usage errors
            code = exc.code if isinstance(exc.code, int) else 2
    return subprocess.CompletedProcess(list(args), code, out.getvalue(), err.getvalue())


def _as_a_terminal_job() -> None:
    """In the child before exec: SIGINT and SIGTERM at their default dispositions, as a terminal's job
    has them. A test process may run with SIGINT ignored (a pytest-xdist worker, a job started in the
    background by a non-interactive shell); a child inherits an ignored signal across exec, and Python
    installs no KeyboardInterrupt handler for a SIGINT it finds ignored."""
    import signal

    signal.signal(signal.SIGINT, signal.SIG_DFL)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)


def start(*args, log: Path, prefix: list[str] | None = None) -> subprocess.Popen:
    """``jointbench ARGS`` in the background, in its own session (its own process group, as a
    terminal's foreground job, its signals at their defaults), stdout and stderr to ``log``."""
    f = open(log, "w")
    return subprocess.Popen([*(prefix or []), sys.executable, "-m", "jointbench", *map(str, args)], cwd=REPO,
                            stdout=f, stderr=subprocess.STDOUT, env=cli_env(), start_new_session=True,
                            preexec_fn=_as_a_terminal_job)


def children(pid: int) -> list[int]:
    """Process ids whose parent is ``pid`` (from /proc)."""
    out = []
    for d in Path("/proc").iterdir():
        if not d.name.isdigit():
            continue
        try:
            stat = (d / "stat").read_bytes()
        except OSError:
            continue
        fields = stat.rsplit(b")", 1)[1].split()
        if int(fields[1]) == pid and fields[0] != b"Z":
            out.append(int(d.name))
    return out


def start_time(pid: int) -> int | None:
    """The start time of process ``pid`` (clock ticks after boot, /proc): with the id, it names one
    process, even when the id is reused later."""
    try:
        return int(Path(f"/proc/{pid}/stat").read_bytes().rsplit(b")", 1)[1].split()[19])
    except (OSError, IndexError, ValueError):
        return None


def alive(pid: int, started: int | None = None) -> bool:
    """The process exists and is not a zombie (and, with ``started``, is the one that started then)."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_bytes()
    except OSError:
        return False
    fields = stat.rsplit(b")", 1)[1].split()
    return fields[0] != b"Z" and (started is None or int(fields[19]) == started)


def wait_for(cond, timeout: float, step: float = 0.05) -> bool:
    t_end = time.monotonic() + timeout
    while time.monotonic() < t_end:
        if cond():
            return True
        time.sleep(step)
    return bool(cond())


def cache_entries(out: Path) -> list[Path]:
    return sorted((out / "cache").glob("??/*.json"))


def temporaries(root: Path) -> list[Path]:
    return sorted(p for p in root.rglob("*.tmp"))


def tiny_grid_part(estimators: list[str] | None = None, realizations: int = 3, **grid) -> dict:
    """A small comparison grid part (protocol compare): a time-varying elbow on a position servo, square or
    sine stiffness, two noise levels; about 0.1 s a case. Without identifiability cases (``identify: false``; a
    grid has them by default)."""
    return {"protocol": "compare", "description": "tiny comparison grid",
            "params": {"realizations": realizations, "ensemble_size": 2, "discard": "1 s", "spread_draws": 20,
                       "identify": False},
            "grid": {"estimator": estimators or ["ibk_spectral", "kbr", "sds"], "scenario": ["elbow"],
                     "variation": ["square"], "noise": [0, 0.05], **grid},
            "scenarios": {"elbow": {
                "experiment": {"joint": {"model": "time_varying", "I": 0.01, "B": 0.5, "K": 50},
                               "perturbation": {"kind": "filtered_noise", "cutoff": "20 Hz", "order": 2,
                                                "rms": "0.02 rad"},
                               "apparatus": {"kind": "position_servo", "stiffness": "30000 N.m/rad"},
                               "fs_sim": "2 kHz", "duration": "8 s", "acquisition": {"fs": "200 Hz"}},
                "stiffness": {"mean": 50, "amplitude": 10, "period": "4 s"}}},
            "variations": {"square": {"shape": "square"}, "sine": {"shape": "sine"}},
            "estimators": {"ibk_spectral": {"fmin": "0 Hz", "fmax": "20 Hz", "segment": "2 s", "overlap": 0.5},
                           "sds": {"window": "0.5 s", "lag_before": "20 ms", "lag_after": "20 ms"},
                           "ensemble_irf": {"lag_before": "10 ms", "lag_after": "10 ms", "pool": "0.05 s"}}}
