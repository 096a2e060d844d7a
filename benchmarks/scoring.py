"""What the protocols score an estimate with: the simulated truth it is compared to, the samples it is
scored on, and the time of its fit. Shared by the comparison protocol (every grid case) and the paper
protocols; the metrics themselves are :mod:`benchmarks.metrics`.
"""
from __future__ import annotations

import time
from typing import Any

import numpy as np


def frozen_stiffness(trial, f_hz: float = 0.0) -> np.ndarray:
    """The true frozen stiffness at every sample of a simulated trial (N·m/rad): the magnitude of the true
    frozen impedance (angle to torque) at ``f_hz`` (0: the static gain, what an IRF's sum and a parametric
    K estimate; the lowest multisine line: what KBR and skirt report). From the trial's input-to-output
    transfer function: itself when the angle is imposed, its inverse when the torque is."""
    return trial.frozen_stiffness(f_hz)      # jointbench.types.Trial.frozen_stiffness: one definition


def scored_samples(time_s: np.ndarray, discard: float) -> np.ndarray:
    """Samples at least ``discard`` seconds from both ends of ``time_s``."""
    return (time_s - time_s[0] >= discard - 1e-9) & (time_s[-1] - time_s >= discard - 1e-9)


def fit_timed(estimator, data) -> tuple[Any, float]:
    """``(estimate, wall seconds)`` of one fit."""
    t0 = time.perf_counter()
    est = estimator.fit(data)
    return est, time.perf_counter() - t0
