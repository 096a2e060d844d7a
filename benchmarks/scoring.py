"""What the protocols score an estimate with: the simulated truth it is compared to, the samples it is
scored on, and the time of its fit. Shared by the comparison protocol (every grid case) and the paper
protocols; the metrics themselves are :mod:`benchmarks.metrics`.
"""
from __future__ import annotations

import time
from typing import Any

import numpy as np

from jointbench.fitting.pipeline import gate


def frozen_stiffness(trial, f_hz: float = 0.0) -> np.ndarray:
    """The true frozen stiffness at every sample of a simulated trial (N·m/rad): the magnitude of the true
    frozen impedance (angle to torque) at ``f_hz`` (0: the static gain, what an IRF's sum and a parametric
    K estimate; the lowest multisine line: what KBR and skirt report). From the trial's input-to-output
    transfer function: itself when the angle is imposed, its inverse when the torque is."""
    return trial.frozen_stiffness(f_hz)      # jointbench.core.types.Trial.frozen_stiffness: one definition


def scored_samples(time_s: np.ndarray, discard: float) -> np.ndarray:
    """Samples at least ``discard`` seconds from both ends of ``time_s``."""
    return (time_s - time_s[0] >= discard - 1e-9) & (time_s[-1] - time_s >= discard - 1e-9)


def fit_timed(estimator, data) -> tuple[Any, float]:
    """``(estimate, wall seconds)`` of one fit, passed through the output gate (:func:`fit_gated`)."""
    t0 = time.perf_counter()
    est = estimator.fit(data)
    seconds = time.perf_counter() - t0
    gate(estimator, est, data)
    return est, seconds


def fit_gated(estimator, data):
    """The estimate of ``estimator`` fitted to ``data``, passed through the output gate of ``jointbench
    estimate`` and :func:`jointbench.api.fit` (:func:`jointbench.fitting.pipeline.gate`): a fit the command
    would refuse raises :class:`~jointbench.core.errors.Refused`, and the case is ``refused``
    (:func:`benchmarks.harness.case.run_case`). The harness scores the estimate against the truth
    afterwards; the gate judges it as a user would see it, against the data."""
    est = estimator.fit(data)
    gate(estimator, est, data)
    return est


def basis_bound(truth: np.ndarray, time_s: np.ndarray, scored: np.ndarray, basis_rows: np.ndarray,
                fit_on: str = "scored") -> float:
    """The lowest RMSE over the ``scored`` samples that any curve in the span of ``basis_rows`` can reach
    against ``truth``: the least-squares projection of ``truth`` onto the basis, fitted on the scored
    samples (``fit_on='scored'``: the exact bound of the scored RMSE) or on every sample
    (``fit_on='window'``: the projection over the whole record, then scored), and its RMSE.

    A skirt estimate of |G(j w_1, t)| is the magnitude of a complex combination of the same basis
    functions; where the phase of G at w_1 varies little over time (the wrist of Table I: a few degrees)
    the magnitude is, to that order, in the real span, so this is the floor of its noise-free RMSE_k.

    Parameters
    ----------
    truth : ndarray
        The true curve at ``time_s``.
    time_s : ndarray
        Sample times (only their number is used: the basis is given at the same samples).
    scored : ndarray of bool
        Samples the RMSE is taken over.
    basis_rows : ndarray
        Shape ``(n_basis, len(time_s))``: e.g. :func:`jointbench.estimators.skirt.basis`.

    References
    ----------
    van de Ruit et al. (2018), eq. 14 (the basis) and eq. 18 (RMSE_k).
    """
    y = np.asarray(truth, float)
    B = np.asarray(basis_rows, float)
    s = np.asarray(scored, bool)
    if B.ndim != 2 or B.shape[1] != len(y) or len(time_s) != len(y) or len(s) != len(y):
        raise ValueError(f"basis_bound: shapes differ: truth {y.shape}, time {np.shape(time_s)}, scored {s.shape}, "
                         f"basis {B.shape}")
    if fit_on not in ("scored", "window"):
        raise ValueError(f"basis_bound: fit_on must be 'scored' or 'window', got {fit_on!r}")
    fit = s if fit_on == "scored" else np.ones_like(s)
    coef, *_ = np.linalg.lstsq(B[:, fit].T, y[fit], rcond=None)
    resid = y[s] - coef @ B[:, s]
    return float(np.sqrt(np.mean(resid ** 2)))
