"""Confidence bands of the ensemble estimators by a delete-a-group jackknife over realizations.

Private module (the leading underscore keeps it out of the estimator registry). Used by
:mod:`estimators.ensemble_irf`, :mod:`estimators.sds` and :mod:`estimators.guarin`, whose estimates
have no closed-form covariance (an MDL pseudo-inverse per time, or a pseudo-inverse of a large basis
expansion).

The realizations of an ensemble are independent repetitions of one time-varying condition. They are cut
into ``G`` groups (``groups``, at most ``R``; realization ``r`` in group ``r mod G``), the ensemble is
fitted again without each group, and the pointwise variance of the stiffness at every sample is
``(G - 1)/G sum_g (k_g - mean k)^2``; the band is ``estimate -+ t_{G-1} se``. Deterministic: no seed.
A resampling over realizations, but not the bootstrap: a bootstrap draw holds about 63 % of the
realizations once or more, and a per-time pseudo-inverse with few realizations per lag (``R`` near
``L``) is much noisier from 63 % of them than from all, so the bootstrap's spread overstated the
estimator's (half-widths 6.8 times 1.96 standard deviations of ensemble_irf's errors, 20 realizations,
9 lags); a jackknife replicate lacks only ``R/G`` of them. The band describes the spread from one set of
realizations to another (the noise and the realizations' own variation), not a bias of the method (a lag
range shorter than the joint's memory, a window or basis too coarse for the time variation). Fewer than
:data:`MIN_REALIZATIONS` realizations: no band.

References
----------
Efron, B. & Stein, C. (1981). The jackknife estimate of variance. Ann. Stat. 9(3), 586-596; Efron, B. &
Tibshirani, R. J. (1993). An Introduction to the Bootstrap. Chapman & Hall, ch. 11 (the jackknife, delete-d).
"""
from __future__ import annotations

import dataclasses
from typing import Callable

import numpy as np

from jointbench.core.ensemble import Ensemble
from jointbench.core.errors import InputError
from jointbench.core.estimate import Intervals
from jointbench.core.intervals import LEVEL, t_quantile
from jointbench.core.schema import param

#: fewest realizations for a jackknife band
MIN_REALIZATIONS = 8


@dataclasses.dataclass(frozen=True)
class JackknifeSettings:
    """The jackknife over realizations of the ensemble estimators' bands."""

    groups: int = param(20, ge=0, doc="groups of realizations left out in turn for the stiffness band (at most "
                                      "the realizations; computed when first asked for); 0 = no band")


def realization_jackknife(name: str, ens: Ensemble, refit: Callable[[Ensemble], object], estimate,
                          settings: JackknifeSettings) -> Intervals | None:
    """Pointwise stiffness band of ``estimate`` (fitted to ``ens``) from ``refit`` without each group.

    A replicate the estimator refuses (e.g. fewer realizations than lags) gives no band (None), as do
    fewer than :data:`MIN_REALIZATIONS` realizations and ``groups = 0``.
    """

    R = ens.size
    G = min(settings.groups, R)
    if G < 2 or R < MIN_REALIZATIONS:
        return None
    t = estimate.time
    ks = []
    for g in range(G):
        keep = [r for r in range(R) if r % G != g]
        try:
            ks.append(np.asarray(refit(ens.subset(keep)).stiffness(t), float))
        except InputError:
            return None
    ks = np.array(ks)
    se = np.sqrt((G - 1) / G * np.sum((ks - ks.mean(axis=0)) ** 2, axis=0))
    q = t_quantile(G - 1)
    k = np.asarray(estimate.stiffness(t), float)
    return Intervals(level=LEVEL, method=f"delete-a-group jackknife over the {R} realizations ({G} groups; t "
                                         f"quantile, {G - 1} dof)",
                     bounds={"stiffness": (k - q * se, k + q * se)}, pointwise=True)
