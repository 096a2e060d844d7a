"""Confidence bands of the ensemble estimators by a bootstrap over realizations.

Private module (the leading underscore keeps it out of the estimator registry). Used by
:mod:`estimators.ensemble_irf`, :mod:`estimators.sds` and :mod:`estimators.guarin`, whose estimates
have no closed-form covariance (an MDL pseudo-inverse per time, or a pseudo-inverse of a large basis
expansion).

The realizations of an ensemble are independent repetitions of one time-varying condition: drawn with
replacement ``R`` at a time (``resamples`` times, from ``seed``), each draw is fitted again, and the
pointwise standard error of the stiffness at every sample is the standard deviation of the refits,
scaled by ``sqrt(R / (R - 1))`` (the bootstrap's variance is the plug-in one, biased by ``(R - 1) / R``);
the band is ``estimate -+ t_{R-1} se``. The band describes the spread from one set of realizations to
another (the noise and the realizations' own variation), not a bias of the method (a lag range shorter
than the joint's memory, a basis too coarse for the time variation). Fewer than
:data:`MIN_REALIZATIONS` realizations: no band (a bootstrap over 3 realizations is no estimate of
anything).

References
----------
Efron, B. & Tibshirani, R. J. (1993). An Introduction to the Bootstrap. Chapman & Hall, ch. 6 (the
bootstrap estimate of standard error) and Sec. 12.5 (the t interval with a bootstrap standard error).
"""
from __future__ import annotations

import dataclasses
from typing import Callable

import numpy as np

from jointbench.ensemble import Ensemble
from jointbench.errors import InputError
from jointbench.estimate import Intervals
from jointbench.schema import param

#: confidence level of the bands
LEVEL = 0.95
#: fewest realizations for a bootstrap band
MIN_REALIZATIONS = 8


@dataclasses.dataclass(frozen=True)
class BootstrapSettings:
    """The bootstrap over realizations of the ensemble estimators' bands."""

    resamples: int = param(50, ge=0, doc="bootstrap draws of the realizations for the stiffness band "
                                         "(computed when first asked for); 0 = no band")
    seed: int = param(0, ge=0, doc="seed of the bootstrap draws (same seed, same band)")


def realization_bootstrap(name: str, ens: Ensemble, refit: Callable[[Ensemble], object], estimate,
                          settings: BootstrapSettings) -> Intervals | None:
    """Pointwise stiffness band of ``estimate`` (fitted to ``ens``) from ``refit`` of bootstrap draws.

    Draws that the estimator refuses (e.g. fewer distinct realizations than lags) are skipped; fewer
    than half the draws fitted, or fewer than :data:`MIN_REALIZATIONS` realizations: None.
    """
    from scipy import stats

    R = ens.size
    if settings.resamples == 0 or R < MIN_REALIZATIONS:
        return None
    rng = np.random.default_rng(settings.seed)
    t = estimate.time
    ks = []
    for _ in range(settings.resamples):
        idx = rng.integers(0, R, R)
        try:
            ks.append(np.asarray(refit(ens.subset(idx)).stiffness(t), float))
        except InputError:
            continue
    if len(ks) < max(2, settings.resamples // 2):
        return None
    se = np.std(np.array(ks), axis=0, ddof=1) * np.sqrt(R / (R - 1.0))
    q = float(stats.t.ppf(0.5 + LEVEL / 2, R - 1))
    k = np.asarray(estimate.stiffness(t), float)
    return Intervals(level=LEVEL, method=f"bootstrap over the {R} realizations ({len(ks)} draws, seed "
                                         f"{settings.seed}; standard error x t quantile, {R - 1} dof)",
                     bounds={"stiffness": (k - q * se, k + q * se)}, pointwise=True)
