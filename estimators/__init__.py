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
from jointbench.registry import Registry, import_submodules, scan_registrations
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


# Names, tags and one-line summaries come from the modules' source; a module is imported when its
# estimator is first used (``jointbench estimate --list`` starts without importing scipy).
REGISTRY.defer(scan_registrations(__name__, __path__))


def import_all() -> None:
    """Import every estimator module (registering everything now rather than on first use)."""
    import_submodules(__name__, __path__)
