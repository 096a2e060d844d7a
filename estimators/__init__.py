"""Estimators: one file per method, registered by ``@register("name")``.

Every estimator is a class with a ``Settings`` dataclass (parsed strictly by
:func:`jointbench.schema.parse`) and a ``fit(trials) -> Estimate`` method. An estimator sees only
:class:`~jointbench.types.Trial` objects, never how they were made: this package imports
``jointbench`` only, never ``sims`` or ``benchmarks``.
"""
from __future__ import annotations

import dataclasses
from abc import ABC, abstractmethod
from typing import Any, ClassVar, Mapping, Sequence

from jointbench.errors import InputError
from jointbench.estimate import Estimate
from jointbench.registry import Registry, import_submodules
from jointbench.schema import parse
from jointbench.types import Trial

REGISTRY: Registry[type["Estimator"]] = Registry("estimator")


def register(name: str, *, tags: Sequence[str] = ()):
    """Class decorator: register an :class:`Estimator` subclass under ``name``."""

    def deco(cls):
        cls.name = name
        return REGISTRY.register(name, tags=tags)(cls)

    return deco


@dataclasses.dataclass(frozen=True)
class NoSettings:
    """For estimators without options."""


class Estimator(ABC):
    """Base class: holds validated settings, fits a list of trials."""

    name: ClassVar[str] = "?"
    Settings: ClassVar[type] = NoSettings
    #: perturbation kinds whose data this estimator can identify from (empty: any)
    perturbations: ClassVar[tuple[str, ...]] = ()

    @classmethod
    def supports(cls, experiment: Any) -> str | None:
        """Why data of ``experiment`` (anything with ``perturbation.kind``) cannot be fitted, or None.

        The harness asks this when it expands a study, so that an impossible pairing (skirt on a PRBS)
        is a config error before any case runs, not a failed case."""
        kind = getattr(getattr(experiment, "perturbation", None), "kind", None)
        if cls.perturbations and kind is not None and kind not in cls.perturbations:
            return (f"{cls.name} needs a {' or '.join(repr(k) for k in cls.perturbations)} perturbation, "
                    f"the experiment has {kind!r}")
        return None

    def __init__(self, settings: Any = None):
        self.settings = self.Settings() if settings is None else settings

    def fit(self, trials: Trial | Sequence[Trial]) -> Estimate:
        """Fit one trial or several records of the same condition (pooled)."""
        if isinstance(trials, Trial):
            trials = [trials]
        trials = list(trials)
        if not trials:
            raise InputError(f"{self.name}: no trial given")
        fs = {t.fs for t in trials}
        if len(fs) > 1:
            raise InputError(f"{self.name}: all records must share one sampling rate, got {sorted(fs)} Hz")
        return self._fit(trials)

    @abstractmethod
    def _fit(self, trials: list[Trial]) -> Estimate:
        """Estimate from validated trials (same ``fs``, at least one)."""


def make(name: str, settings: Mapping[str, Any] | None = None, where: str = "settings") -> Estimator:
    """Instantiate registered estimator ``name`` with strictly parsed ``settings``."""
    cls = REGISTRY.get(name)
    return cls(parse(cls.Settings, settings, f"{where} (estimator '{name}')"))


import_submodules(__name__, __path__)
