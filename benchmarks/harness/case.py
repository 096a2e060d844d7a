"""One case: a JSON-serialisable specification and the function that computes it.

``run_case(case) -> CaseResult`` is a pure function of the case: its numbers depend only on what the
protocol can see (the :class:`~benchmarks.protocols.Context`: part name, seed, parameters with the
sweep values, experiment and estimators), on the code this module imports and its protocol's and
estimators' modules (their import closure, :meth:`Case.code_modules`,
:func:`benchmarks.harness.fingerprint.case_code_hash`) and on the numerical libraries. The cache key is
built from exactly those (:func:`Case.key_material`). Keep this module free of harness imports (config,
tables, figures, reports): everything it imports is hashed into the key.
"""
from __future__ import annotations

import contextlib
import dataclasses
import time
import traceback
from typing import Any, Mapping

from jointbench import estimators
from jointbench import sims
from jointbench.benchmarks import protocols
from jointbench.core.errors import Refused
from jointbench.core.schema import Problems, parse
from jointbench.sims import reuse
from jointbench.sims.backend import record_simulations


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
    where: str            # "<config file>: parts.<name>", for messages only (not part of the key)
    backend: str = "analytic"      # the simulation backend of the part (or of --backend)

    def spec(self) -> dict:
        return dataclasses.asdict(self)

    @property
    def case_id(self) -> str:
        """``part-key=value...-seedN`` (the sweep or grid values in order)."""
        sw = "".join(f"-{k}={v}" for k, v in self.sweep.items())
        return f"{self.part}{sw}-seed{self.seed}"

    def key_material(self) -> dict:
        """What the protocol sees: every field but ``study`` and ``where`` (no paths), and the contents
        (SHA-256) of every input file the case reads (:func:`input_files`): an edited profile CSV is a new
        case, whether or not the config pins its ``sha256``."""
        material = {"protocol": self.protocol, "part": self.part, "params": self.params, "sweep": self.sweep,
                    "experiment": self.experiment, "estimators": self.estimators, "seed": self.seed,
                    "backend": self.backend}
        files = input_files(self)
        if files:
            material["inputs"] = [[name, content_hash(name)] for name in files]
        return material

    def code_modules(self) -> tuple[str, ...]:
        """The modules that compute this case besides the shared closure of this module: its protocol's
        and its estimators' (registered lazily, imported on first use), found from the registries without
        importing them. An estimator is used when it is in ``estimators`` or named in the parameters (a
        protocol may make one by name, e.g. ``estimators_without_noise``). Its closure is part of the
        case's key (:func:`benchmarks.harness.fingerprint.case_code_hash`)."""
        used = set(self.estimators) | {s for s in _strings((self.params, self.sweep)) if s in estimators.REGISTRY}
        mods = {protocols.REGISTRY.module_of(self.protocol)} | {estimators.REGISTRY.module_of(n) for n in used}
        return tuple(sorted(m for m in mods if m))


def _strings(obj):
    """Every string among the keys and values of nested mappings and sequences."""
    if isinstance(obj, str):
        yield obj
    elif isinstance(obj, Mapping):
        for k, v in obj.items():
            yield from _strings(k)
            yield from _strings(v)
    elif isinstance(obj, (list, tuple)):
        for v in obj:
            yield from _strings(v)


@dataclasses.dataclass
class CaseResult:
    case: Case
    status: str                    # "ok", "failed", or "refused" (the output gate refused an estimate: error says why)
    rows: list[dict]
    curves: list[dict]
    wall_time_s: float
    error: str = ""
    detail: str = ""               # traceback of a failure (for the log, not the table)
    cached: bool = False           # served from the cache rather than computed in this run
    sim_times: list = dataclasses.field(default_factory=list)   # [backend, seconds, reused] per simulated trial

    @property
    def refusals(self) -> list[str]:
        """Reasons of the fits the output gate refused: every fit of a ``refused`` case (its ``error``), or some
        fits of an ``ok`` case whose other fits were kept (:meth:`benchmarks.protocols.Context.refused`)."""
        if self.status == "refused":
            return [self.error]
        return protocols.refusals(self.rows) if self.status == "ok" else []

    def to_json(self) -> dict:
        d = dataclasses.asdict(self)
        d["case"] = self.case.spec()
        return d

    @classmethod
    def from_json(cls, d: dict) -> "CaseResult":
        d = dict(d)
        d["case"] = Case(**d["case"])
        return cls(**d)


def input_files(case: Case) -> list[str]:
    """The files a case reads, as its config names them: every ``{shape: file, path: ...}`` profile of its
    experiment and parameters (:mod:`sims.profile_file`), sorted, each once."""
    found: set[str] = set()

    def walk(obj) -> None:
        if isinstance(obj, Mapping):
            if obj.get("shape") == "file" and isinstance(obj.get("path"), str):
                found.add(obj["path"])
            for v in obj.values():
                walk(v)
        elif isinstance(obj, (list, tuple)):
            for v in obj:
                walk(v)

    walk([case.experiment, case.params, case.sweep])
    return sorted(found)


_HASHES: dict = {}


def content_hash(path: str) -> str:
    """SHA-256 of a file's contents ('missing' or 'unreadable: ...' when it cannot be read), remembered by
    its size and modification time (a case's key is asked for several times per run)."""
    import hashlib
    import os
    import stat

    try:
        st = os.stat(path)
    except OSError:
        return "missing"
    if not stat.S_ISREG(st.st_mode):
        return "not a regular file"            # a FIFO or a device: never opened (it could block)
    stamp = (os.path.abspath(path), st.st_size, st.st_mtime_ns, st.st_ino)
    got = _HASHES.get(stamp)
    if got is None:
        h = hashlib.sha256()
        try:
            with open(path, "rb") as f:
                for block in iter(lambda: f.read(1 << 20), b""):
                    h.update(block)
            got = h.hexdigest()
        except OSError as exc:
            got = f"unreadable: {exc.strerror}"
        _HASHES[stamp] = got
    return got


def parse_inputs(case: Case):
    """The protocol, parsed parameters, experiment and estimators of a case (raises ConfigError)."""
    proto = protocols.REGISTRY.get(case.protocol)
    problems, params, exp, ests = Problems(), None, None, {}
    with problems.catch():                 # the errors of the parameters, experiment and estimators at once
        params = parse(proto.Params, {**case.params, **case.sweep}, f"{case.where}: params")
    if case.experiment is not None:
        with problems.catch():
            exp = sims.Experiment.from_mapping(case.experiment, f"{case.where}: experiment", backend=case.backend)
    for name, settings in case.estimators.items():
        with problems.catch():
            ests[name] = estimators.make(name, settings, f"{case.where}: estimators.{name}")
    problems.raise_all()
    return proto, params, exp, ests


def run_case(case: Case) -> CaseResult:
    """Run one case; never raises but KeyboardInterrupt: a failure (any exception, ``SystemExit`` of a
    plugin's ``sys.exit`` included) is returned as ``status='failed'`` with its error, an estimate the output
    gate refused (:class:`~jointbench.core.errors.Refused`) as ``status='refused'`` with its reason.

    Trials of the case that share a response (an estimation and a validation trial, a record with and
    without noise) simulate it once (:mod:`sims.reuse`), inside the group's block when one is open."""
    t0 = time.perf_counter()
    try:
        proto, params, exp, ests = parse_inputs(case)
        ctx = protocols.Context(part=case.part, seed=case.seed, params=params, experiment=exp,
                                estimators=ests)
        with record_simulations() as log, (contextlib.nullcontext() if reuse.active() else reuse.reuse_responses()):
            proto.fn(ctx)
        refused = protocols.refusals(ctx.rows)
        every = bool(refused) and all(r.get("metric") == protocols.REFUSED for r in ctx.rows)
        return CaseResult(case, "refused" if every else "ok", ctx.rows, ctx.curves, time.perf_counter() - t0,
                          error="; ".join(refused), sim_times=[[b, round(t, 6), int(r)] for b, t, r in log])
    except Refused as exc:    # the output gate (jointbench.fitting.pipeline.gate): not a failure, a refusal
        row = protocols.refused_row(str(exc.diagnostics.get("estimator", "")), exc)
        return CaseResult(case, "refused", [row], [], time.perf_counter() - t0, error=row["reason"])
    except BaseException as exc:  # noqa: BLE001 - a failing case (sys.exit in a plugin too) must not stop the others
        if isinstance(exc, KeyboardInterrupt):
            raise                                  # Ctrl-C is the run's to handle, not a failed case
        return CaseResult(case, "failed", [], [], time.perf_counter() - t0,
                          error=f"{type(exc).__name__}: {exc}", detail=traceback.format_exc())


def run_group(cases: list[Case], on_result=None) -> list[CaseResult]:
    """Cases scheduled together (one task of an executor): each response they share is simulated once
    (one :func:`sims.reuse.reuse_responses` block around them all); every number is what
    :func:`run_case` gives for each case alone (tests/test_reuse.py). ``on_result`` is called with each
    result as it finishes (a worker stores it at once: a lost scheduler loses no finished case)."""
    out = []
    with reuse.reuse_responses():
        for c in cases:
            out.append(run_case(c))
            if on_result is not None:
                on_result(out[-1])
    return out


_ONE_THREAD: list = []


def limit_process_to_one_blas_thread() -> None:
    """One BLAS thread per process (the pool already uses every core; nested BLAS threads would
    oversubscribe them, which slowed a 0.16 s KBR fit to seconds on 2 cores). Serial runs use one
    thread too, so that serial and parallel runs give bit-identical numbers. Set once per process."""
    if _ONE_THREAD:
        return
    from threadpoolctl import threadpool_limits

    _ONE_THREAD.append(threadpool_limits(limits=1))
