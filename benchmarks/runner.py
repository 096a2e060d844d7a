"""Expand a study into independent cases and run them (process pool, cache, failures recorded).

A case is a pure function of its specification and seed: ``run_case(case) -> CaseResult``. Cases are
JSON-serialisable and keyed by a hash of their specification and of the code, so they can be run on
any machine and served from ``results/<study>/cache/`` (a crash loses no finished case).
"""
from __future__ import annotations

import concurrent.futures as cf
import dataclasses
import hashlib
import json
import os
import subprocess
import sys
import time
import traceback
from pathlib import Path
from typing import Any, Callable, Iterable, Mapping

import estimators
import sims
from benchmarks import protocols
from benchmarks.config import REPO, Part, Study
from jointbench.errors import ConfigError
from jointbench.schema import parse
from sims.backend import record_simulations


@dataclasses.dataclass(frozen=True)
class Case:
    """One independent unit of work."""

    study: str
    part: str
    protocol: str
    params: Mapping[str, Any]
    sweep: Mapping[str, Any]
    experiment: Mapping[str, Any] | None
    estimators: Mapping[str, Mapping[str, Any]]
    seed: int
    where: str
    backend: str = "analytic"      # the simulation backend of the part (or of --backend)

    def spec(self) -> dict:
        return dataclasses.asdict(self)

    @property
    def case_id(self) -> str:
        sw = "".join(f"-{k}={v}" for k, v in self.sweep.items())
        return f"{self.part}{sw}-seed{self.seed}"

    def key(self, fingerprint: str) -> str:
        blob = json.dumps(self.spec(), sort_keys=True, default=str) + fingerprint
        return hashlib.sha256(blob.encode()).hexdigest()[:24]


@dataclasses.dataclass
class CaseResult:
    case: Case
    status: str                    # "ok" or "failed"
    rows: list[dict]
    curves: list[dict]
    wall_time_s: float
    error: str = ""
    detail: str = ""               # traceback of a failure (for the log, not the table)
    sim_times: list = dataclasses.field(default_factory=list)   # [backend, seconds] per simulated trial

    def to_json(self) -> dict:
        d = dataclasses.asdict(self)
        d["case"] = self.case.spec()
        return d

    @classmethod
    def from_json(cls, d: dict) -> "CaseResult":
        d = dict(d)
        d["case"] = Case(**d["case"])
        return cls(**d)


def _parse_inputs(case: Case):
    proto = protocols.REGISTRY.get(case.protocol)
    params = parse(proto.Params, {**case.params, **case.sweep}, f"{case.where}: params")
    exp = None
    if case.experiment is not None:
        exp = sims.Experiment.from_mapping(case.experiment, f"{case.where}: experiment", backend=case.backend)
    ests = {name: estimators.make(name, settings, f"{case.where}: estimators.{name}")
            for name, settings in case.estimators.items()}
    return proto, params, exp, ests


def expand(study: Study, parts: Iterable[str] | None = None, backend: str | None = None) -> list[Case]:
    """All cases of the selected parts, validated up front (config errors surface before any run).
    ``backend`` (e.g. ``jointbench run --backend mujoco``) replaces every part's own backend."""
    names = list(study.parts) if parts is None else list(parts)
    unknown = [p for p in names if p not in study.parts]
    if unknown:
        raise ConfigError(f"{study.path}: unknown part {unknown[0]!r}; parts: {', '.join(study.parts)}")
    cases = []
    for name in names:
        part: Part = study.parts[name]
        for combo in part.grid():
            for seed in part.seeds:
                case = Case(study=study.id, part=name, protocol=part.protocol, params=dict(part.params),
                            sweep=combo, experiment=part.experiment, estimators=dict(part.estimators),
                            seed=seed, where=part.where, backend=backend or part.backend)
                cases.append(case)
        _parse_inputs(cases[-1])   # validate once per part
    return cases


def run_case(case: Case) -> CaseResult:
    """Run one case; never raises: a failure is returned as ``status='failed'`` with its error."""
    t0 = time.perf_counter()
    try:
        proto, params, exp, ests = _parse_inputs(case)
        ctx = protocols.Context(part=case.part, seed=case.seed, params=params, experiment=exp,
                                estimators=ests)
        with record_simulations() as log:
            proto.fn(ctx)
        return CaseResult(case, "ok", ctx.rows, ctx.curves, time.perf_counter() - t0,
                          sim_times=[[b, round(t, 6)] for b, t in log])
    except Exception as exc:  # noqa: BLE001 - a failing case must not stop the others
        return CaseResult(case, "failed", [], [], time.perf_counter() - t0,
                          error=f"{type(exc).__name__}: {exc}", detail=traceback.format_exc())


def code_fingerprint() -> str:
    """Hash of the package sources: a cached case is reused only with identical code."""
    h = hashlib.sha256()
    for pkg in ("jointbench", "sims", "estimators", "benchmarks"):
        for p in sorted((REPO / pkg).rglob("*.py")):
            h.update(p.relative_to(REPO).as_posix().encode())
            h.update(p.read_bytes())
    return h.hexdigest()[:16]


def git_commit() -> str:
    try:
        out = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=REPO, capture_output=True,
                             text=True, timeout=10)
        if out.returncode:
            return "unknown"
        dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"], cwd=REPO,
                               capture_output=True, text=True, timeout=10).stdout.strip()
        return out.stdout.strip() + ("-dirty" if dirty else "")
    except (OSError, subprocess.SubprocessError):
        return "unknown"


class Cache:
    """One JSON file per finished case, written atomically."""

    def __init__(self, folder: Path, fingerprint: str, enabled: bool = True):
        self.folder, self.fingerprint, self.enabled = folder, fingerprint, enabled
        self.hits = 0     # entries served by get()

    def _path(self, case: Case) -> Path:
        return self.folder / f"{case.case_id}-{case.key(self.fingerprint)}.json"

    def get(self, case: Case) -> CaseResult | None:
        p = self._path(case)
        if not self.enabled or not p.is_file():
            return None
        try:
            res = CaseResult.from_json(json.loads(p.read_text()))
        except (ValueError, TypeError, KeyError):
            return None   # a damaged entry is recomputed
        self.hits += 1
        return res

    def put(self, res: CaseResult) -> None:
        if not self.enabled or res.status != "ok":
            return
        self.folder.mkdir(parents=True, exist_ok=True)
        p = self._path(res.case)
        tmp = p.with_suffix(".tmp")
        tmp.write_text(json.dumps(res.to_json()))
        os.replace(tmp, p)
        for old in self.folder.glob(f"{res.case.case_id}-*.json"):   # entries of older code or specs
            if old != p:
                old.unlink(missing_ok=True)


def _progress(total: int, enabled: bool):
    if not enabled:
        return None
    from tqdm import tqdm

    return tqdm(total=total, unit="case", file=sys.stderr, dynamic_ncols=True)


def _one_blas_thread() -> None:
    """Worker initializer: one BLAS thread per worker process (the pool already uses every core; nested
    BLAS threads would oversubscribe them, which slowed a 0.16 s KBR fit to seconds on 2 cores). Serial
    runs use one thread too, so that serial and parallel runs give bit-identical numbers."""
    from threadpoolctl import threadpool_limits

    threadpool_limits(limits=1)


def run_cases(cases: list[Case], cache: Cache, workers: int | None = None, serial: bool = False,
              progress: bool = True, on_result: Callable[[CaseResult], None] | None = None
              ) -> list[CaseResult]:
    """Run cases (cached ones are reused) on a process pool, or serially; order is preserved."""
    results: dict[int, CaseResult] = {}
    todo = []
    for i, c in enumerate(cases):
        hit = cache.get(c)
        if hit is not None:
            results[i] = hit
        else:
            todo.append(i)
    bar = _progress(len(cases), progress)
    if bar is not None:
        bar.update(len(results))
        bar.set_postfix_str(f"{len(results)} cached")

    def done(i: int, res: CaseResult) -> None:
        results[i] = res
        cache.put(res)
        if on_result:
            on_result(res)
        if bar is not None:
            bar.update(1)
            if res.status != "ok":
                bar.write(f"case {res.case.case_id} failed: {res.error}")

    workers = workers or os.cpu_count() or 1
    if serial or workers == 1 or len(todo) <= 1:
        from threadpoolctl import threadpool_limits

        with threadpool_limits(limits=1):   # as in the workers: same BLAS reductions, same numbers
            for i in todo:
                done(i, run_case(cases[i]))
    else:
        with cf.ProcessPoolExecutor(max_workers=min(workers, len(todo)), initializer=_one_blas_thread) as pool:
            futs = {pool.submit(run_case, cases[i]): i for i in todo}
            for fut in cf.as_completed(futs):
                i = futs[fut]
                try:
                    res = fut.result()
                except Exception as exc:  # noqa: BLE001 - e.g. a worker killed by the OS
                    res = CaseResult(cases[i], "failed", [], [], 0.0, error=f"{type(exc).__name__}: {exc}")
                done(i, res)
    if bar is not None:
        bar.close()
    return [results[i] for i in range(len(cases))]
