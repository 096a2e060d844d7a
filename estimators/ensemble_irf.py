"""Ensemble time-varying two-sided IRF (MacNeil, Kearney & Hunter 1992; ``tv_ident`` of REKLAB/NLID)."""
from __future__ import annotations

import dataclasses
from typing import Literal

import numpy as np

from jointbench.estimators import register
from jointbench.estimators._resample import JackknifeSettings, realization_jackknife
from jointbench.estimators._tvirf import EnsembleEstimator, TVLagSettings, centred, fill_invalid, lagged, mdl_solve
from jointbench.core.ensemble import Ensemble
from jointbench.core.errors import InputError
from jointbench.core.estimate_tv import TVIRFEstimate
from jointbench.core.schema import param


def _moving_sum(x: np.ndarray, width: int) -> np.ndarray:
    """Sums of ``width`` consecutive entries along axis 0 (``len(x) - width + 1`` of them)."""
    if width == 1:
        return x
    c = np.cumsum(x, axis=0)
    out = c[width - 1:].copy()
    out[1:] -= c[:-width]
    return out


@register("ensemble_irf", tags=("ltv", "nonparametric", "irf", "ensemble"))
class EnsembleIRF(EnsembleEstimator):
    """Time-varying two-sided IRF fitted at every sample across the realizations of an ensemble.

    At sample ``t`` the ``R`` realizations give ``R`` equations ``y_r(t) = sum_k h(k, t) u_r(t - k)``,
    ``k = -M1 ... M2``, in the ``L = M1 + M2 + 1`` unknowns ``h(., t)``. With the means removed
    (``remove_mean``; by default the ensemble mean at every sample, which takes out whatever the
    realizations share, such as a voluntary torque pattern), the input covariance
    ``Phi(t) = (1/R) sum_r x_r(t) x_r(t)^T`` (``x_r(t)`` the lagged input) and cross-covariance
    ``phi(t) = (1/R) sum_r x_r(t) y_r(t)`` are formed for all samples at once, and ``Phi(t) h = phi(t)``
    is solved by a pseudo-inverse whose order (number of singular vectors) minimises the minimum
    description length ``(1 + d ln R / R)(var y(t) - explained_d)`` (``solver = 'mdl'``): with few
    realizations the weakly excited directions, which mostly carry noise, are left out.
    ``solver = 'full'`` keeps every singular vector (least squares).

    ``pool`` (default 0: the method as published) adds the samples within ``+-pool`` seconds of ``t``
    to its equations (the IRF taken constant over ``2 pool``): ``R (2P + 1)`` equations per time, for
    ensembles with fewer realizations than lags. An extension, not MacNeil et al.'s method.

    Parameters
    ----------
    settings : Settings
        ``lag_before``, ``lag_after`` (s, default 0.04 each); ``remove_mean`` ('ensemble', 'record',
        'none'); ``pool`` (s); ``solver`` ('mdl' or 'full'); ``rcond``.

    Notes
    -----
    Takes an :class:`~jointbench.core.ensemble.Ensemble` only. Needs at least as many equations per time
    as lags: ``R (2P + 1) >= L`` (else :class:`InputError`). Returns a
    :class:`~jointbench.core.estimate.TVIRFEstimate`, valid from sample ``M2 + P`` to ``n - 1 - M1 - P``
    (the lags and the pool stay inside the record), held outside; ``h`` is not scaled by ``1/fs``
    (REKLAB's ``tv_ident`` returns ``h fs``).

    References
    ----------
    MacNeil, J. B., Kearney, R. E. & Hunter, I. W. (1992). Identification of time-varying biological
    systems from ensemble data (joint dynamics application). IEEE Trans. Biomed. Eng. 39(12), 1213-1225.
    Westwick, D. T. & Kearney, R. E. (1997). Med. Biol. Eng. Comput. 35, 83-90 (MDL order selection).
    """

    accepts = frozenset({"ensemble"})

    @dataclasses.dataclass(frozen=True)
    class Settings(TVLagSettings, JackknifeSettings):
        remove_mean: Literal["ensemble", "record", "none"] = param(
            "ensemble", doc="'ensemble': the mean over realizations at every sample (MacNeil et al.); 'record': "
                            "each realization's own mean; 'none'")
        pool: float = param(0.0, unit="s", ge=0, doc="also use the samples within +-pool of each time "
                                                     "(0 = the published method)")

    def _fit_ensemble(self, ens: Ensemble) -> TVIRFEstimate:
        s = self.settings
        fs, n, R = ens.fs, ens.n, ens.size
        m1, m2 = self._lags(ens)
        L = m1 + m2 + 1
        P = int(round(s.pool * fs))
        width = 2 * P + 1
        if R * width < L:
            pooled = f" x {width} pooled samples" if P else ""
            raise InputError(f"{self.name}: ensemble '{ens.name}' has {R} realizations{pooled} = {R * width} "
                             f"equations per time for {L} lags (lag_before = {s.lag_before:g} s, lag_after = "
                             f"{s.lag_after:g} s at {fs:g} Hz); needs at least as many realizations as lags: "
                             f"shorten the lags, add realizations or pool neighbouring samples (setting 'pool')")
        if n - (L - 1) - 2 * P < L:
            raise InputError(f"{self.name}: ensemble '{ens.name}' has {n} samples per realization: the {L} lags "
                             f"and {2 * P} pooled samples leave {max(0, n - (L - 1) - 2 * P)} samples whose lags lie "
                             f"in the record, fewer than the lags (need {2 * L - 1 + 2 * P} samples; settings "
                             f"'lag_before', 'lag_after', 'pool'): too short a record to follow a time course")
        from jointbench.estimators._small_eigh import lagged_gram          # compiled (numba): on first use

        U, Y = centred(self.name, ens, s.remove_mean)
        X = lagged(U, m1, m2)                       # (n - L + 1, R, L): row i is sample i + M2
        Yv = Y[m2:n - m1]
        n_obs = R * width
        Phi = _moving_sum(lagged_gram(U, L), width)                          # X[i]^T X[i] for every i
        phi = _moving_sum(np.einsum("trl,tr->tl", X, Yv), width)
        yy = _moving_sum(np.einsum("tr,tr->t", Yv, Yv), width)
        for a in (Phi, phi, yy):                    # per observation (new arrays: in place)
            a /= n_obs
        hv, order = mdl_solve(Phi, phi, yy, n_obs, s.solver, s.rcond)
        valid = np.zeros(n, bool)
        valid[m2 + P:n - m1 - P] = True
        h = np.zeros((L, n))
        h[:, valid] = hv.T
        info = {"realizations": R, "pool_samples": P, "equations_per_time": n_obs,
                "order": f"{int(order.min())} ... {int(order.max())} of {L} (median {int(np.median(order))})",
                "remove_mean": s.remove_mean}
        est = TVIRFEstimate(lags=np.arange(-m1, m2 + 1), h=fill_invalid(h, valid), fs=fs, time=ens.time,
                             valid=valid, estimator=self.name, info=info)
        return est.with_intervals(lambda: realization_jackknife(self.name, ens, self._fit_ensemble, est, s))
