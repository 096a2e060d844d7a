"""The conformance kit: :func:`check_estimator` runs every check on an estimator, built-in or a plugin's.

As scikit-learn's ``check_estimator`` and ``benchopt test``: a method developer calls it in the tests of a new
estimator, and ``make test`` calls it on every registered one (tests/test_conformance.py)::

    from jointbench.testing import check_estimator

    def test_conformance():
        check_estimator("sliding_ibk")          # or the class itself

It fits records of the estimator's own kind (:mod:`jointbench.testing.data`: simulated through
:mod:`jointbench.sims`, the kind read from ``accepts``, ``perturbations`` and the tags) through the user's fitting
path, and runs the checks of :mod:`jointbench.testing.checks` (:data:`CHECKS`): blind fitting, settings validated,
the data kinds it accepts, degenerate inputs, invariances (torque scale, time shift, units), interval coverage,
and issue 33's narrow-band record over a grid of its lag and window settings. A failing check raises an
:class:`AssertionError` naming the check, the estimator, the setting and the input (record, seed).

This room (floor 4, beside the harness) imports the simulators and the fitting path, never the harness.
"""
from __future__ import annotations

import dataclasses
import time
from typing import Iterable

from jointbench.testing.checks import (CHECKS, check_blind, check_data_kinds, check_degenerate_inputs,
                                       check_interval_coverage, check_narrow_band, check_output_gate,
                                       check_settings_validated,
                                       check_time_shift, check_torque_scaling, check_units)
from jointbench.testing.kit import CheckSkipped

__all__ = ["CHECKS", "CheckSkipped", "Report", "check_blind", "check_data_kinds", "check_degenerate_inputs",
           "check_estimator", "check_interval_coverage", "check_narrow_band", "check_output_gate",
           "check_settings_validated",
           "check_time_shift", "check_torque_scaling", "check_units", "estimator_class", "run_check"]


@dataclasses.dataclass(frozen=True)
class Outcome:
    """One check's outcome: ``status`` 'passed', 'skipped' or 'failed', and what it found (its note, the reason it
    was skipped, or the failure)."""

    check: str
    status: str
    detail: str
    seconds: float


@dataclasses.dataclass
class Report:
    """The checks run on one estimator (:func:`check_estimator`)."""

    estimator: str
    quick: bool
    outcomes: list[Outcome] = dataclasses.field(default_factory=list)

    def of(self, status: str) -> list[Outcome]:
        return [o for o in self.outcomes if o.status == status]

    @property
    def failed(self) -> list[Outcome]:
        return self.of("failed")

    def __str__(self) -> str:
        lines = [f"conformance of {self.estimator} ({'quick' if self.quick else 'full'}): "
                 f"{len(self.of('passed'))} passed, {len(self.of('skipped'))} skipped, {len(self.failed)} failed"]
        lines += [f"  {o.status:7} {o.check} ({o.seconds:.1f} s): {o.detail}" for o in self.outcomes]
        return "\n".join(lines)


def estimator_class(name_or_class):
    """The estimator class of a registered name, or the class itself (a subclass of
    :class:`jointbench.estimators.Estimator`)."""
    from jointbench import estimators

    if isinstance(name_or_class, str):
        return estimators.REGISTRY.get(name_or_class)
    if isinstance(name_or_class, type) and issubclass(name_or_class, estimators.Estimator):
        name = name_or_class.name
        if name not in estimators.REGISTRY.names() or estimators.REGISTRY.get(name) is not name_or_class:
            raise TypeError(f"check_estimator: {name_or_class.__qualname__} is not the estimator registered as "
                            f"{name!r}; register it first (@jointbench.estimators.register): the fitting path "
                            f"looks an estimator's kind up by its name")
        return name_or_class
    raise TypeError(f"check_estimator: expected a registered estimator name or an Estimator subclass, got "
                    f"{name_or_class!r}")


def run_check(name_or_class, check: str, *, quick: bool = True) -> str:
    """Run one check of :data:`CHECKS` on an estimator: its note; :class:`CheckSkipped` or an AssertionError."""
    if check not in CHECKS:
        raise KeyError(f"no conformance check {check!r}; the checks: {', '.join(CHECKS)}")
    return CHECKS[check](estimator_class(name_or_class), quick=quick)


def check_estimator(name_or_class, *, quick: bool = True, checks: Iterable[str] | None = None,
                    raise_on_failure: bool = True, verbose: bool = False) -> Report:
    """Run the conformance checks on an estimator and report them.

    Parameters
    ----------
    name_or_class : str or type
        A registered estimator name (``jointbench.estimators.REGISTRY``) or an Estimator subclass.
    quick : bool
        Few seeds and the ends of the settings grid (``make test``); False: the full version
        (``make conformance``: 20 seeds of coverage, 30 narrow-band seeds at every setting of the grid).
    checks : iterable of str, optional
        Names of :data:`CHECKS` to run (default: all).
    raise_on_failure : bool
        Raise an AssertionError (the report's text) when a check failed; else only return the report.
    verbose : bool
        Print the report.

    Returns
    -------
    Report
        Every check's outcome: passed (with its note), skipped (with the reason), failed (with the failure).

    References
    ----------
    Pedregosa et al. (2011), scikit-learn, ``sklearn.utils.estimator_checks.check_estimator``.
    """
    cls = estimator_class(name_or_class)
    names = list(CHECKS) if checks is None else list(checks)
    report = Report(cls.name, quick)
    for name in names:
        start = time.process_time()
        try:
            status, detail = "passed", run_check(cls, name, quick=quick)
        except CheckSkipped as exc:
            status, detail = "skipped", str(exc)
        except AssertionError as exc:
            status, detail = "failed", str(exc)
        report.outcomes.append(Outcome(name, status, detail, time.process_time() - start))
    if verbose:
        print(report)
    if raise_on_failure and report.failed:
        raise AssertionError(str(report))
    return report
