"""Small inputs for the catalogue's cases: tiny studies, grids, profiles, recordings (self-contained: the
catalogue does not import the tests)."""
from __future__ import annotations

import copy
import shutil
import socket
import subprocess
from pathlib import Path

import numpy as np
import yaml

PUBLISHED = {"study": None, "source": "catalogue", "checks": [
    {"id": "T-K", "part": "fit", "description": "K of the fit", "source": "-", "published": 50, "low": 40,
     "high": 60, "select": {"metric": "K"}, "evidence": "sanity", "tolerance_reason": "catalogue band"}]}

EXPERIMENT = {"joint": {"model": "second_order", "I": 0.01, "B": 0.5, "K": 50},
              "perturbation": {"kind": "filtered_noise", "cutoff": "20 Hz", "order": 2, "rms": "0.02 rad"},
              "apparatus": {"kind": "position_servo", "stiffness": "30000 N.m/rad"},
              "fs_sim": "2 kHz", "duration": "4 s", "acquisition": {"fs": "500 Hz"}}
ESTIMATORS = {"ibk_spectral": {"fmin": "0 Hz", "fmax": "20 Hz", "segment": "2 s", "overlap": 0.5}}


def fit_part(seeds=2, experiment=None, estimators=None, **extra) -> dict:
    return {"protocol": "parametric_fit", "description": "second-order fit", "seeds": seeds,
            "experiment": copy.deepcopy(experiment or EXPERIMENT),
            "estimators": copy.deepcopy(estimators or ESTIMATORS), **extra}


def grid_part(**grid) -> dict:
    """A small comparison grid: a time-varying elbow, square stiffness, two noise levels (about 0.1 s a case)."""
    return {"protocol": "compare", "description": "catalogue grid",
            "params": {"realizations": 2, "ensemble_size": 2, "discard": "1 s", "spread_draws": 10},
            "grid": {"estimator": ["ibk_spectral"], "scenario": ["elbow"], "variation": ["square"],
                     "noise": [0, 0.05], **grid},
            "scenarios": {"elbow": {
                "experiment": {"joint": {"model": "time_varying", "I": 0.01, "B": 0.5, "K": 50},
                               "perturbation": {"kind": "filtered_noise", "cutoff": "20 Hz", "order": 2,
                                                "rms": "0.02 rad"},
                               "apparatus": {"kind": "position_servo", "stiffness": "30000 N.m/rad"},
                               "fs_sim": "2 kHz", "duration": "6 s", "acquisition": {"fs": "200 Hz"}},
                "stiffness": {"mean": 50, "amplitude": 10, "period": "3 s"}}},
            "variations": {"square": {"shape": "square"}, "sine": {"shape": "sine"}},
            "perturbations": {"prbs": {"kind": "prbs", "amplitude": 0.02, "clock": "20 ms"}},
            "estimators": copy.deepcopy(ESTIMATORS)}


def study(ws, parts: dict | None = None, study_id: str = "cat", name: str | None = None, edit=None,
          published=None) -> Path:
    """Write a study config (and its published values) into the workspace; returns its path."""
    folder = ws.path("configs")
    folder.mkdir(exist_ok=True)
    parts = parts if parts is not None else {"fit": fit_part()}
    pub = folder / f"{name or study_id}_published.yaml"
    checks = dict(PUBLISHED, study=study_id)
    if "fit" not in parts:
        checks = dict(checks, checks=[])
    pub.write_text(yaml.safe_dump(checks, sort_keys=False))
    data = {"study": study_id, "title": "catalogue study", "paper": "none",
            "published": str(pub) if published is None else published, "not_reproduced": [], "parts": parts}
    if edit:
        edit(data)
    path = folder / f"{name or study_id}.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False, allow_unicode=True))
    return path


def profile_csv(path: Path, t_end: float = 10.0, low: float = 40.0, high: float = 60.0, n: int = 11) -> Path:
    t = np.linspace(0.0, t_end, n)
    v = np.where(np.arange(n) % 2, high, low)
    path.write_text("time,value\n" + "".join(f"{a:g},{b:g}\n" for a, b in zip(t, v)))
    return path


def recording_csv(path: Path, seconds: float = 20.0, fs: float = 500.0, seed: int = 0) -> Path:
    """A plausible recording: a second-order joint (I 0.01, B 0.5, K 50) driven by filtered noise."""
    from scipy import signal

    rng = np.random.default_rng(seed)
    n = int(seconds * fs)
    t = np.arange(n) / fs
    b, a = signal.butter(2, 20 / (fs / 2))
    angle = signal.lfilter(b, a, rng.standard_normal(n)) * 0.02
    vel = np.gradient(angle, 1 / fs)
    acc = np.gradient(vel, 1 / fs)
    torque = 0.01 * acc + 0.5 * vel + 50 * angle + 0.002 * rng.standard_normal(n)
    with open(path, "w") as f:
        f.write("time,angle,torque\n")
        np.savetxt(f, np.column_stack([t, angle, torque]), delimiter=",", fmt="%.9g")
    return path


def ensemble_npz(path: Path, realizations: int = 20, samples: int = 2000, fs: float = 500.0,
                 transpose: bool = False, time_scale: float = 1.0) -> Path:
    rng = np.random.default_rng(1)
    ang = rng.standard_normal((samples, realizations)) * 0.02
    tq = 50 * ang + 0.01 * rng.standard_normal((samples, realizations))
    t = np.arange(samples) / fs * time_scale
    if transpose:
        ang, tq = ang.T, tq.T
    np.savez(path, angle=ang, torque=tq, time=t)
    return path


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def unshare_ok() -> bool:
    if shutil.which("unshare") is None:
        return False
    return subprocess.run(["unshare", "-m", "--propagation", "private", "true"], capture_output=True).returncode == 0


def need_unshare():
    return None if unshare_ok() else "needs unshare -m (mount namespaces) for a read-only or full disk"


def tmpfs_prefix(mount: Path, size_kb: int, seed: Path | None = None, free_kb: int | None = None,
                 after: Path | None = None) -> list[str]:
    """Run the command with ``mount`` on a private tmpfs of ``size_kb`` (a full disk without root tricks
    outside a mount namespace): ``seed``'s contents are copied in first, the disk is filled to leave
    ``free_kb``, and the contents are copied to ``after`` when the command ends (to inspect them)."""
    lines = [f'mkdir -p "{mount}"', f'mount -t tmpfs -o size={size_kb}k tmpfs "{mount}" || exit 97']
    if seed is not None:
        lines.append(f'cp -a "{seed}/." "{mount}/" 2>/dev/null')
    if free_kb is not None:
        lines.append(f'avail=$(df -k --output=avail "{mount}" | tail -1); n=$((avail - {free_kb})); '
                     f'[ $n -gt 0 ] && dd if=/dev/zero of="{mount}/.fill" bs=1k count=$n 2>/dev/null')
    lines.append('"$@"; rc=$?')
    if after is not None:
        lines.append(f'mkdir -p "{after}"; cp -a "{mount}/." "{after}/" 2>/dev/null; rm -f "{after}/.fill"')
    lines.append("exit $rc")
    return ["unshare", "-m", "--propagation", "private", "sh", "-c", "; ".join(lines), "sh"]


def readonly_prefix(folder: Path) -> list[str]:
    script = f'mount --bind "{folder}" "{folder}" && mount -o remount,bind,ro "{folder}" && exec "$@"'
    return ["unshare", "-m", "--propagation", "private", "sh", "-c", script, "sh"]


def snapshot(folder: Path) -> dict[str, bytes]:
    """Every regular file under ``folder`` (relative path -> contents), without the cache, locks and temporaries."""
    out = {}
    if not folder.is_dir():
        return out
    for p in sorted(folder.rglob("*")):
        rel = p.relative_to(folder).as_posix()
        if p.is_file() and not rel.startswith("cache/") and not p.name.endswith((".lock", ".tmp")) \
                and "history.sqlite" not in p.name and p.name != ".fill":
            out[rel] = p.read_bytes()
    return out
