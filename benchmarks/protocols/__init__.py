"""Protocols: what one case of a study part computes (one file per study or family).

A protocol is a function ``fn(ctx: Context) -> None`` registered with :func:`register`, together with a
``Params`` dataclass parsed strictly from the part's ``params`` (plus its sweep values). It reads the
parsed experiment and estimators from the context, and records tidy metric rows and curves (for the
figures) through ``ctx.metric`` and ``ctx.curve``. Protocols are pure functions of the case and seed.
"""
from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any, Callable, Mapping

import numpy as np

from jointbench.core.registry import Registry, package_modules, scan_modules


@dataclasses.dataclass(frozen=True)
class Protocol:
    """``fn(ctx)`` computes one case; ``share(params)``, when given, names what of the parameters decides
    the simulated response: cases of one experiment, seed and backend whose ``share`` values are equal
    are scheduled together so that each response is simulated once (:mod:`sims.reuse`). It only groups;
    which responses really are equal is decided by the simulator, so a coarse ``share`` costs time, never
    a number."""

    name: str
    fn: Callable[["Context"], None]
    Params: type
    share: Callable[[Any], Any] | None = None


REGISTRY: Registry[Protocol] = Registry("protocol")


def register(name: str, params: type, *, tags: tuple[str, ...] = (), share: Callable[[Any], Any] | None = None):
    """Register ``fn(ctx)`` as protocol ``name`` with parameter dataclass ``params`` (and ``share``, see
    :class:`Protocol`)."""

    def deco(fn):
        REGISTRY.register(name, tags=tags, module=fn.__module__)(Protocol(name, fn, params, share))
        return fn

    return deco


#: the metric of a row recording a fit the output gate refused (:meth:`Context.refused`)
REFUSED = "refused"


def refused_row(estimator: str, exc: Exception, **labels: Any) -> dict:
    """The row recording a fit the output gate refused: ``metric`` :data:`REFUSED`, the reason
    (``"<reason code>: <message>"``) and ``labels``."""
    return {"metric": REFUSED, "value": float("nan"), "estimator": estimator,
            "reason": f"{getattr(exc, 'reason', 'refused')}: {exc}", **labels}


def refusals(rows: list[dict]) -> list[str]:
    """The reasons of the refused fits among a case's ``rows`` (:meth:`Context.refused`)."""
    return [str(r.get("reason", "")) for r in rows if r.get("metric") == REFUSED]


@dataclasses.dataclass
class Context:
    """Everything one case may use, and where it puts its results."""

    part: str
    seed: int
    params: Any
    experiment: Any
    estimators: Mapping[str, Any]
    rows: list[dict] = dataclasses.field(default_factory=list)
    curves: list[dict] = dataclasses.field(default_factory=list)
    _rng: np.random.Generator | None = dataclasses.field(default=None, init=False, repr=False)

    @property
    def rng(self) -> np.random.Generator:
        """The case's generator for protocol-level draws (independent of the simulator's streams): one per
        case, created on first use from the seed, so successive draws continue one stream."""
        if self._rng is None:
            self._rng = np.random.default_rng(np.random.SeedSequence([self.seed, 0x5EED]))
        return self._rng

    def metric(self, metric: str, value: float, estimator: str = "", **labels: Any) -> None:
        """Record one tidy row (labels become columns, e.g. ``fs_hz=250``)."""
        self.rows.append({"metric": metric, "value": float(value), "estimator": estimator, **labels})

    def refused(self, estimator: str, exc: Exception, **labels: Any) -> None:
        """Record that the output gate (:func:`jointbench.fitting.pipeline.gate`) refused one fit of the case: a
        row ``metric='refused'`` with the reason (:data:`REFUSED`). The case's other fits (other estimators,
        other inputs) keep their rows; the case is counted as refused (:func:`refusals`) and stays
        selectable for the checks that read the other fits."""
        self.rows.append(refused_row(estimator, exc, **labels))

    def curve(self, name: str, x, y, series: str = "", **labels: Any) -> None:
        """Record a curve for the figures (stored long: one row per point)."""
        x = np.asarray(x, float)
        y = np.asarray(y, float)
        if x.shape != y.shape:
            raise ValueError(f"curve {name!r}: x and y differ in shape {x.shape} vs {y.shape}")
        self.curves.append({"curve": name, "series": series, "x": x.tolist(), "y": y.tolist(), **labels})


def _modules() -> list[tuple[str, Path]]:
    """Every protocol module: this package's own (the generic one), the comparison grid's and each study's."""
    from jointbench.benchmarks import studies

    compare = ("jointbench.benchmarks.compare.protocol", Path(__path__[0]).parent / "compare" / "protocol.py")
    return [*package_modules(__name__, __path__), compare, *studies.modules("protocol")]


# Names and tags come from the modules' source; a protocol's module is imported when a case first uses it
# (``jointbench list`` and the study module start without importing scipy.signal or any protocol).
REGISTRY.defer(scan_modules(_modules()))


def import_all() -> None:
    """Import every protocol module (registering everything now rather than on first use)."""
    import importlib

    for module, _ in _modules():
        importlib.import_module(module)
