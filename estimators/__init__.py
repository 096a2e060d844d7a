"""Estimators: one file per method, registered by ``@register("name")``.

Every estimator is a class with a ``Settings`` dataclass (parsed strictly by
:func:`jointbench.core.schema.parse`, and checked on construction) and a ``fit(trials) -> Estimate`` method.
An estimator sees only :class:`~jointbench.core.types.Trial` objects without their truth (it fits blind), never
how they were made: this package imports
the core of ``jointbench`` only, never ``jointbench.sims`` or ``jointbench.benchmarks``. Installed as
``jointbench.estimators`` (the repository's ``estimators/`` folder).
"""
from __future__ import annotations

import dataclasses
import functools
from abc import ABC, abstractmethod
from typing import Any, ClassVar, Mapping, Sequence

from jointbench.core.ensemble import DATA_KINDS, Ensemble, data_kind
from jointbench.core.errors import InputError, Refused
from jointbench.core.estimate import Estimate, estimate_problem, non_finite
from jointbench.core.registry import Registry, import_submodules, scan_registrations
from jointbench.core.schema import checked, parse
from jointbench.core.types import Trial

#: the estimators: the built-in ones, and those of installed plugins (entry-point group jointbench.estimators)
REGISTRY: Registry[type["Estimator"]] = Registry("estimator", entry_points="jointbench.estimators")


def register(name: str, *, tags: Sequence[str] = ()):
    """Class decorator: register an :class:`Estimator` subclass under ``name``."""

    def deco(cls):
        if not (isinstance(cls, type) and issubclass(cls, Estimator)):
            raise TypeError(f"estimator {name!r}: {cls!r} must subclass jointbench.estimators.Estimator "
                            f"(its fit checks the data and hides the truth)")
        cls.name = name
        return REGISTRY.register(name, tags=tags)(cls)

    return deco


def blind(data, estimator: str = "?"):
    """``data`` (a trial, records or an ensemble) without its truth: what :meth:`Estimator.fit` hands on."""
    if isinstance(data, (Trial, Ensemble)):
        return data.blind(estimator)
    if isinstance(data, (list, tuple)):
        return [t.blind(estimator) if isinstance(t, Trial) else t for t in data]
    return data


def _fits_blind(fit):
    """``fit`` receiving its data without the truth (:class:`~jointbench.core.types.HiddenTruth`)."""
    if getattr(fit, "_fits_blind", False):
        return fit

    @functools.wraps(fit)
    def wrapper(self, trials, *args, **kwargs):
        return fit(self, blind(trials, getattr(self, "name", "?")), *args, **kwargs)

    wrapper._fits_blind = True
    return wrapper


@dataclasses.dataclass(frozen=True)
class NoSettings:
    """For estimators without options."""


class Estimator(ABC):
    """Base class: holds validated settings, fits a trial, pooled records or an ensemble.

    ``accepts`` declares the kinds of data the estimator takes (:data:`jointbench.core.ensemble.DATA_KINDS`):
    ``trial`` (one record), ``pooled`` (several records of one stationary condition, fitted together)
    and ``ensemble`` (an :class:`~jointbench.core.ensemble.Ensemble`: realizations of one time-varying
    condition, aligned in time). Anything else is a one-line :class:`InputError`, and a harness can ask
    :meth:`refuses` first to skip with the reason.
    """

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
    #: the kinds of data fitted (:data:`DATA_KINDS`): one record by default; an estimator whose fit uses
    #: every record given (pooled) says so with "pooled", one that fits ensembles with "ensemble"
    accepts: ClassVar[frozenset[str]] = frozenset({"trial"})

    def __init_subclass__(cls, **kwargs):
        """Every estimator's ``Settings`` checks its values on construction, as :func:`make` does
        (:func:`jointbench.core.schema.checked`): ``IRFLeastSquares.Settings(lag_before=-5.0)`` is refused. And
        every estimator fits blind: a subclass that overrides :meth:`fit` itself gets its data without the
        truth too."""
        super().__init_subclass__(**kwargs)
        checked(cls.Settings)
        if "fit" in cls.__dict__:
            cls.fit = _fits_blind(cls.__dict__["fit"])

    def __init__(self, settings: Any = None):
        self.settings = self.Settings() if settings is None else settings

    @classmethod
    def refuses(cls, data) -> str | None:
        """Why this estimator does not take ``data`` (its kind is not in ``accepts``), or ``None``."""
        kind = data_kind(data)
        if kind in cls.accepts:
            return None
        takes = " or ".join({"trial": "single trials", "pooled": "pooled records", "ensemble": "ensembles"}[k]
                            for k in DATA_KINDS if k in cls.accepts)
        if kind == "ensemble":
            hint = "; give its realizations as a list of records to pool them" if "pooled" in cls.accepts else ""
            return f"{cls.name}: takes {takes}, not an ensemble ('{data.name}', {data.size} realizations){hint}"
        if kind == "trial":
            name = data.name if isinstance(data, Trial) else list(data)[0].name
            return f"{cls.name}: takes {takes}, not a single trial ('{name}')"
        hint = ("; to fit them as realizations of one time-varying condition, give them as an Ensemble"
                if "ensemble" in cls.accepts else "")
        return f"{cls.name}: fits one record at a time (takes {takes}), got {len(list(data))} records{hint}"

    @_fits_blind
    def fit(self, trials: Trial | Sequence[Trial] | Ensemble) -> Estimate:
        """Fit one trial, several records of the same condition (pooled) or an ensemble.

        Blind: the estimator sees the data without their truth (a simulated trial's ``truth`` is replaced
        by :class:`~jointbench.core.types.HiddenTruth`, which raises :class:`~jointbench.core.types.TruthHidden` when
        read); the caller's trials keep theirs for scoring."""
        if isinstance(trials, Ensemble):
            why = self.refuses(trials)
            if why:
                raise InputError(why)
            return self.checked(self._fit_ensemble(trials), [trials.n], trials.fs)
        if isinstance(trials, Trial):
            trials = [trials]
        trials = list(trials)
        if not trials:
            raise InputError(f"{self.name}: no trial given")
        fs = {t.fs for t in trials}
        if len(fs) > 1:
            raise InputError(f"{self.name}: all records must share one sampling rate, got {sorted(fs)} Hz")
        why = self.refuses(trials)
        if why:
            raise InputError(why)
        return self.checked(self._fit(trials), [t.n for t in trials], trials[0].fs)

    def checked(self, estimate: Estimate, lengths: Sequence[int], fs: float) -> Estimate:
        """``estimate`` when it is a valid result of a fit of records of ``lengths`` samples at ``fs`` Hz: an
        :class:`~jointbench.core.estimate.Estimate` on the data's time base, each parameter a scalar or one
        value per sample, every value finite (:func:`~jointbench.core.estimate.estimate_problem`,
        :func:`~jointbench.core.estimate.non_finite`). Every caller (the fit pipeline, the harness, a
        notebook) gets a valid estimate or :class:`~jointbench.core.errors.Refused` naming this estimator
        and what is wrong, never an estimate that fails later."""
        problem = estimate_problem(estimate, lengths, fs)
        if problem:
            raise Refused(f"{self.name}: the estimate is not valid: {problem} (a bug of the estimator, not of "
                          f"the data)", reason="invalid_estimate",
                          diagnostics={"estimator": self.name, "problem": problem})
        bad = non_finite(estimate, bounds=False)
        if bad:
            raise Refused(f"{self.name}: the fit gave non-finite values in {', '.join(bad)}: the data do not "
                          f"determine them (constant or far too small/large signals, too few samples, or "
                          f"settings the record cannot support)", reason="non_finite",
                          diagnostics={"estimator": self.name, "columns": bad})
        return estimate

    def _fit_ensemble(self, ensemble: Ensemble) -> Estimate:
        """Ensemble mode of a single-trial estimator: fit the ensemble average (van de Ruit et al.
        2018, Table II). Ensemble estimators override this."""
        return self._fit([ensemble.average()])

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
