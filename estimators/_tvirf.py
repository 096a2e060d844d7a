"""Shared pieces of the time-varying IRF estimators (``ensemble_irf``, ``sds``, ``guarin``).

Private module (the leading underscore keeps it out of the estimator registry): the lag settings of
the ensemble methods, the lagged input of every realization, mean removal, and the batched
pseudo-inverse whose order is chosen by the minimum description length (MDL).

References
----------
MacNeil, J. B., Kearney, R. E. & Hunter, I. W. (1992). Identification of time-varying biological systems
from ensemble data. IEEE Trans. Biomed. Eng. 39(12), 1213-1225 (SVD pseudo-inverse per time).

Westwick, D. T. & Kearney, R. E. (1997). Identification of physiological systems: a robust method for
non-parametric impulse response estimation. Med. Biol. Eng. Comput. 35, 83-90 (the pseudo-inverse
order chosen by MDL from the output variance explained by each singular vector).
"""
from __future__ import annotations

import dataclasses
import functools
from typing import Literal

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view
from threadpoolctl import ThreadpoolController

from jointbench.estimators import Estimator
from jointbench.core.ensemble import Ensemble
from jointbench.core.errors import InputError
from jointbench.core.schema import param
from jointbench.core.types import Trial

Solver = Literal["mdl", "full"]


@dataclasses.dataclass(frozen=True)
class TVLagSettings:
    """Lag range and pseudo-inverse of the ensemble IRF estimators (defaults: +-40 ms, the IRF of
    van de Ruit et al. 2018, Sec. V-E, at 100 Hz: 9 lags)."""

    lag_before: float = param(0.04, unit="s", ge=0,
                              doc="anticipatory memory: negative lags down to -M1, M1 = round(lag_before*fs)")
    lag_after: float = param(0.04, unit="s", ge=0,
                             doc="causal memory: positive lags up to M2 = round(lag_after*fs)")
    solver: Solver = param("mdl", doc="'mdl': pseudo-inverse keeping the singular vectors that minimise the "
                                      "MDL; 'full': every singular vector above rcond (least squares)")
    rcond: float = param(1e-10, gt=0, lt=1, doc="singular values below rcond x the largest are never kept")


class EnsembleEstimator(Estimator):
    """Base of the estimators whose natural data is an ensemble: a trial or a list of records is fitted
    as an ensemble (of one, or of those records); subclasses implement ``_fit_ensemble``."""

    def _fit(self, trials: list[Trial]):
        return self._fit_ensemble(as_ensemble(self.name, trials))

    def _lags(self, ens: Ensemble) -> tuple[int, int]:
        """``(M1, M2)``, refused when a nonzero lag is less than half a sample (e.g. time in ms read as s)."""
        try:
            from jointbench.estimators._twosided import lag_samples

            return lag_samples(self.settings, ens.fs)
        except InputError as exc:
            raise InputError(f"{self.name}: ensemble '{ens.name}': {exc}") from None


def lag_samples(settings: TVLagSettings, fs: float) -> tuple[int, int]:
    """``(M1, M2)`` in samples."""
    return int(round(settings.lag_before * fs)), int(round(settings.lag_after * fs))


def as_ensemble(name: str, data: Ensemble | list[Trial]) -> Ensemble:
    """The data as an :class:`Ensemble` (a list of trials becomes one; a single trial is an ensemble of one)."""
    if isinstance(data, Ensemble):
        return data
    return Ensemble(tuple(data), name=data[0].name if len(data) == 1 else f"{name} records")


def centred(name: str, ens: Ensemble, mode: str) -> tuple[np.ndarray, np.ndarray]:
    """Input and output arrays ``(n, R)`` with the means removed as ``mode`` says.

    ``'ensemble'``: the ensemble mean at every sample (MacNeil et al. 1992: what is common to all
    realizations, e.g. a voluntary torque pattern, is not response to the perturbation);
    ``'record'``: each realization's own mean; ``'none'``.

    Raises
    ------
    InputError
        The input is zero after the removal (e.g. the same perturbation in every realization with
        ``'ensemble'``).
    """
    U, Y = ens.inputs, ens.outputs              # stacked anew at every call (Ensemble.inputs): centred in place
    scale = _abs_max(U) or 1.0
    if mode == "ensemble":
        U -= U.mean(axis=1, keepdims=True)
        Y -= Y.mean(axis=1, keepdims=True)
    elif mode == "record":
        U -= U.mean(axis=0)
        Y -= Y.mean(axis=0)
    if not _abs_max(U) > 1e-9 * scale:
        if mode == "ensemble" and ens.size > 1:
            raise InputError(f"{name}: the input is the same in every realization of ensemble '{ens.name}', so "
                             f"removing the ensemble mean (remove_mean = 'ensemble') leaves nothing to identify; "
                             f"give each realization its own perturbation or use remove_mean = 'record'")
        raise InputError(f"{name}: the input (imposed {ens.imposed}) is constant; nothing to identify")
    return U, Y


def _abs_max(a: np.ndarray) -> float:
    """``max |a|`` without the temporary ``|a|``."""
    return float(max(a.max(), -a.min()))


def lagged(U: np.ndarray, m1: int, m2: int) -> np.ndarray:
    """``X[i, r, j] = U[i + M2 - (j - M1), r]``: the input at lags ``k = j - M1`` for sample ``t = i + M2``.

    A read-only strided view of shape ``(n - M1 - M2, R, L)``; row ``i`` belongs to sample ``i + M2``
    (the rows whose lags all fall inside the record).
    """
    L = m1 + m2 + 1
    return sliding_window_view(U, L, axis=0)[..., ::-1]


_CONTROLLER: ThreadpoolController | None = None


def blas_single_thread():
    """Context with one BLAS thread, for the many tiny products and factorizations of these estimators
    (threads only add waiting: 10-20 times slower on a loaded 2-core machine). The controller is made
    once: finding the BLAS libraries reads /proc and costs milliseconds per call."""
    global _CONTROLLER
    if _CONTROLLER is None:
        _CONTROLLER = ThreadpoolController()
    return _CONTROLLER.limit(limits=1)


def gram_stack(X: np.ndarray) -> np.ndarray:
    """``X[i]^T X[i]`` for every row of a stack ``(rows, R, L)``: ``(rows, L, L)``, with one BLAS thread
    (thousands of tiny products gain nothing from threads and lose much on a loaded machine)."""
    with blas_single_thread():
        return np.matmul(X.transpose(0, 2, 1), X)


@functools.lru_cache(maxsize=16)
def _symmetric_gather(M: int, L: int) -> np.ndarray:
    """Where each entry of the ``M L x M L`` Kronecker Gram lies among the products of the pairs
    ``m <= m'`` (rows) and ``l <= l'`` (columns) that :func:`basis_normal` forms: ``G[(m, l), (m', l')]`` is
    entry ``(pair(m, m'), pair(l, l'))`` of that ``(M(M+1)/2, L(L+1)/2)`` product, flattened (read-only)."""
    def pairs(k):
        at = np.zeros((k, k), int)
        i, j = np.triu_indices(k)
        at[i, j] = at[j, i] = np.arange(len(i))
        return at, len(i)
    pm, _ = pairs(M)
    pl, nl = pairs(L)
    idx = (pm[:, None, :, None] * nl + pl[None, :, None, :]).reshape(M * L, M * L)
    idx.flags.writeable = False
    return idx


def basis_normal(X: np.ndarray, Y: np.ndarray, Phi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Normal equations of ``y_r(t) = sum_k sum_m c[m, k] phi_m(t) x_r(t, k)``: ``G`` (M L x M L) and ``b``.

    ``G = sum_t (phi(t) phi(t)^T) (x) S(t)`` with ``S(t) = sum_r x_r(t) x_r(t)^T``, ``b = sum_t phi(t) (x)
    sum_r x_r(t) y_r(t)``: the least squares of Guarin & Kearney's basis-function TV-IRF
    (:class:`estimators.guarin.Guarin`, the intrinsic pathway of ``tv_parallel_cascade``).

    ``G`` is one long, thin product over the samples, ``sum_t p(t) s(t)^T``, of the products of basis
    functions ``p(t) = phi_m(t) phi_m'(t)`` and the entries ``s(t) = S_ll'(t)``. Both factors are
    symmetric in their pair, so only the pairs ``m <= m'`` and ``l <= l'`` are formed (about a third of
    the products of all pairs: 231 x 45 of 441 x 81 for 21 functions and 9 lags) and ``G`` is gathered
    from them. Each entry is the same sum over ``t`` as the product of all pairs computes.

    Parameters
    ----------
    X : ndarray (T, R, L)
        Lagged input of every realization at each of ``T`` samples.
    Y : ndarray (T, R)
        Output of every realization.
    Phi : ndarray (T, M)
        Basis functions of time at the samples.

    References
    ----------
    Guarin, D. L. & Kearney, R. E. (2017). Estimation of time-varying, intrinsic and reflex dynamic joint
    stiffness during movement. Front. Comput. Neurosci. 11:51, Sec. 2 (the expanded least squares).
    """
    T, M = Phi.shape
    L = X.shape[2]
    m, m2 = np.triu_indices(M)
    lag, lag2 = np.triu_indices(L)
    S = gram_stack(X)[:, lag, lag2]                      # (T, L(L+1)/2)
    PhiT = Phi.T
    P = PhiT[m] * PhiT[m2]                                # (M(M+1)/2, T): rows over the samples
    with blas_single_thread():                            # a long, thin product: threads only wait
        G = (P @ S).ravel()[_symmetric_gather(M, L)]
    return G, basis_rhs(X, Y, Phi)


def basis_rhs(X: np.ndarray, Y: np.ndarray, Phi: np.ndarray) -> np.ndarray:
    """``b = sum_t phi(t) (x) sum_r x_r(t) y_r(t)``: the right-hand side of :func:`basis_normal`."""
    q = np.einsum("trl,tr->tl", X, Y)
    return (Phi.T @ q).reshape(-1)


def mdl_solve(Phi: np.ndarray, phi: np.ndarray, yvar: np.ndarray, n_obs: float, solver: Solver,
              rcond: float) -> tuple[np.ndarray, np.ndarray]:
    """Pseudo-inverse solutions of a stack of normal equations ``Phi[t] h[t] = phi[t]``.

    ``Phi[t] = V diag(s) V^T`` (eigenvalues descending). The output variance explained by singular
    vector ``i`` is ``(v_i^T phi)^2 / s_i``; keeping the ``d`` largest leaves the residual variance
    ``yvar - sum_{i<=d}``; the MDL chooses ``d`` minimising ``(1 + d ln(n_obs) / n_obs) * residual``
    (``solver='mdl'``), or every vector above ``rcond`` times the largest singular value (``'full'``).

    Parameters
    ----------
    Phi : ndarray (T, L, L)
        Input covariance matrices (per observation).
    phi : ndarray (T, L)
        Input-output cross-covariances (per observation).
    yvar : ndarray (T,)
        Output variance (per observation).
    n_obs : float
        Observations behind each equation set (the MDL's sample size).

    Returns
    -------
    h : ndarray (T, L)
    order : ndarray of int (T,)
        Singular vectors kept.

    Notes
    -----
    The eigendecompositions, orders and solutions are computed in one compiled loop over the stack
    (:mod:`jointbench.estimators._small_eigh`; numpy's ``linalg.eigh``, one LAPACK call per matrix, cost
    three quarters of an ensemble fit, issue 22, and a quarter of a cold vanderuit2018_table2, issue 34).
    """
    from jointbench.estimators._small_eigh import mdl_pinv       # numba: imported on first use

    return mdl_pinv(Phi, phi, yvar, n_obs, solver == "full", rcond)


def fill_invalid(h: np.ndarray, valid: np.ndarray) -> np.ndarray:
    """Hold ``h`` (lags x time) from the nearest valid sample outside the valid span."""
    idx = np.flatnonzero(valid)
    out = h.copy()
    out[:, :idx[0]] = h[:, idx[:1]]
    out[:, idx[-1] + 1:] = h[:, idx[-1:]]
    return out
