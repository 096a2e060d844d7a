"""Pointwise covariance of the FSEWLS estimate and the automatic choice of its forgetting rate.

Private module (the leading underscore keeps it out of the estimator registry); used by
:mod:`estimators.fsewls`. Pure functions of the regressors ``Phi`` (``n_records x n x 3``), the
regression output ``y`` (``n_records x n``) and the estimate ``Theta`` (``n x 3``).

References
----------
Xu, Y. & Hollerbach, J. M. (1998). Identification of human joint mechanical properties from single trial
data. IEEE Trans. Biomed. Eng. 45(9), eqs. 5-6 (the exponentially weighted least squares).

Newey, W. K. & West, K. D. (1987). A simple, positive semi-definite, heteroskedasticity and
autocorrelation consistent covariance matrix. Econometrica 55(3), 703-708 (the sandwich with a lag
kernel; here the kernel is the EWLS's own weighting).
"""
from __future__ import annotations

import numpy as np
from scipy import signal as sps

from jointbench.estimators._fsewls_kernels import UPPER3
from jointbench.core.intervals import z_quantile
from jointbench.core.scores import vaf


def _decay(x: np.ndarray, c: float) -> np.ndarray:
    """``z[k] = c z[k-1] + x[k]`` along the last axis (time)."""
    return sps.lfilter([1.0], [1.0, -c], x, axis=-1)


def ewls_variances(Phi: np.ndarray, y: np.ndarray, Theta: np.ndarray, dt: float, lam: float,
                   delay: int, keep: np.ndarray, R0: np.ndarray, m0: int) -> np.ndarray:
    """Covariance of ``Theta(t)``, ``R(t)^-1 S(t) R(t)^-1``, shape (n, 3, 3).

    The EWLS estimate is ``Theta(t) = R(t)^-1 r(t)``, started from the least-squares fit of the first ``m0``
    samples (``R0``, ``r0``: :func:`estimators._fsewls_kernels.ewls_start`), so that
    ``R(t) = c^t R0 + sum_{s <= t} c^(t-s) Phi_s Phi_s^T dt`` (``c = e^{-lam dt}``) and the error is
    ``R(t)^-1 z(t)``, ``z(t) = c^t a + b(t)`` with ``a = sum_{s < m0} Phi_s e_s dt`` and
    ``b(t) = sum_{s <= t} c^(t-s) Phi_s e_s dt``, ``e`` the equation noise. That noise is coloured by the
    state-variable filter on time scales like ``1/lam`` itself. With ``e`` stationary with autocovariance
    ``gamma(k)`` and independent of the (given) regressors, ``S(t) = Var z(t)`` exactly:

    - ``Var b(t) = sum_{s <= t} c^(2(t-s)) [gamma(0) Phi_s Phi_s^T + Phi_s q_s^T + q_s Phi_s^T] dt^2`` with the
      causal ``q_s = sum_{k >= 1} c^k gamma(k) Phi_{s-k}`` (each pair of samples counted once, from the later);
    - ``Var a = sum_{r < m0} Phi_r g_r^T dt^2`` and ``Cov(b(t), a) = sum_{r <= t} c^(t-r) Phi_r g_r^T dt^2``,
      with ``g_r = sum_{s < m0} gamma(|s - r|) Phi_s``.

    ``gamma`` is estimated from held-out residuals ``e(t) = y(t) - Phi(t)^T Theta(t - delay)``
    (:func:`delayed_prediction_vaf`) on the ``keep`` samples (the fitted residuals would underestimate it
    badly, the estimate following the noise within its short memory), up to ``6 / lam`` lags with
    Bartlett's taper, so that it is an autocovariance (positive semidefinite) and ``S(t)`` the variance it
    claims to be: never negative on the diagonal. (The symmetric approximation used before, each sample's
    weight applied to its neighbours on both sides, is not a variance near the record's start: its diagonal
    came out negative, bands of zero width, issue 33; and ``R(t)`` without ``c^t R0`` made the band
    +-3.5e7 at ``t = 0``.) Records pool by summing ``R`` and ``S``. The symmetric ``S`` and ``R`` are kept as
    their 6 unique entries and ``R^-1`` by its adjugate; only the diagonal of the sandwich is formed (the bands
    need no more: the gate computes them on every fit, and the full (n, 3, 3) matrix products and
    ``numpy.linalg.inv`` cost 6 times the fit itself on a 48 s record, 80 against 12 ms).

    References
    ----------
    Newey, W. K. & West, K. D. (1987), Econometrica 55(3), 703-708 (Bartlett's taper keeps the estimated
    autocovariance positive semidefinite).
    """
    nr, n, _ = Phi.shape
    i, j = UPPER3
    Th = np.concatenate([np.repeat(Theta[:1], delay, axis=0), Theta[:n - delay]]) if delay else Theta
    e = y - np.einsum("rni,ni->rn", Phi, Th)
    ok = keep.copy()
    ok[:delay] = False
    e = np.where(ok, e, 0.0)
    m = int(ok.sum()) * nr
    K = min(n - 1, int(np.ceil(6.0 / (lam * dt))))
    nfft = 1 << int(np.ceil(np.log2(2 * n)))
    E = np.fft.rfft(e, nfft, axis=-1)
    k = np.arange(K + 1)
    gamma = np.fft.irfft(np.sum(np.abs(E) ** 2, axis=0), nfft)[:K + 1] / max(m, 1) * (1.0 - k / (K + 1.0))
    c = np.exp(-lam * dt)
    P = np.ascontiguousarray(np.moveaxis(Phi, 2, 0))                          # (3, nr, n): rows contiguous in time
    taps = np.concatenate([[0.0], c ** k[1:] * gamma[1:]])
    q = sps.oaconvolve(P, taps[None, None, :], mode="full", axes=2)[:, :, :n]
    pp = np.einsum("krn,krn->kn", P[i], P[j])                                 # (6, n): Phi Phi^T's unique entries
    om = gamma[0] * pp + np.einsum("krn,krn->kn", P[i], q[j]) + np.einsum("krn,krn->kn", q[i], P[j])
    S = _decay(om * (dt * dt), c * c)
    # g_r = sum_{s < m0} gamma(|s - r|) Phi_s: zero from r = m0 + K on, so formed on the first L samples only
    L = max(1, min(n, m0 + K))
    g = sps.fftconvolve(P[:, :, :m0], np.concatenate([gamma[:0:-1], gamma])[None, None, :], mode="full",
                        axes=2)[:, :, K:K + L] if m0 else np.zeros((3, nr, L))
    # Phi_r g_r^T + g_r Phi_r^T (unique entries): Var a is half its sum over r < m0, Cov(b, a) plus its
    # transpose is its decay (the filter is linear; past L it decays freely: c^(t - L + 1) times its last value)
    pg = (np.einsum("krn,krn->kn", P[i, :, :L], g[j]) + np.einsum("krn,krn->kn", g[i], P[j, :, :L])) * (dt * dt)
    ck = np.exp(-lam * dt * np.arange(n))                                     # c^t
    cov_ba = np.empty((6, n))
    cov_ba[:, :L] = _decay(pg, c)
    cov_ba[:, L:] = np.outer(cov_ba[:, L - 1], ck[1:n - L + 1])
    S += np.outer(0.5 * pg[:, :m0].sum(axis=1), ck * ck) + ck * cov_ba
    R = _decay(pp * dt, c) + np.outer(R0[i, j], ck)                           # R(t) with the start
    Ri = _spd3_inverse(R)
    # diag(Ri S Ri), both symmetric: sum_a Ri_ka^2 S_aa + 2 sum_{a<b} Ri_ka Ri_kb S_ab, in packed entries
    at = [[0, 1, 2], [1, 3, 4], [2, 4, 5]]                                    # packed index of entry (a, b)
    out = np.empty((n, 3))
    for row in range(3):
        r = [Ri[at[row][a]] for a in range(3)]
        out[:, row] = (r[0] * r[0] * S[0] + r[1] * r[1] * S[3] + r[2] * r[2] * S[5]
                       + 2.0 * (r[0] * r[1] * S[1] + r[0] * r[2] * S[2] + r[1] * r[2] * S[4]))
    return out


def _spd3_inverse(R: np.ndarray) -> np.ndarray:
    """Inverses of symmetric positive definite 3 x 3 matrices given by their unique entries ``(6, n)``
    (order :data:`UPPER3`: 00, 01, 02, 11, 12, 22), by the adjugate of the unit-diagonal scaled matrix (the
    scaling keeps I, B and K, of very different sizes, from losing digits); the same layout."""
    d = 1.0 / np.sqrt(R[[0, 3, 5]])
    i, j = UPPER3
    dd_ = d[i] * d[j]
    a, b, c, dd, e, f = R * dd_
    adj = np.stack([dd * f - e * e, c * e - b * f, b * e - c * dd,
                    a * f - c * c, b * c - a * e, a * dd - b * b])
    det = a * adj[0] + b * adj[1] + c * adj[2]
    return adj * (dd_ / det)


def delayed_prediction_vaf(Phi: np.ndarray, y: np.ndarray, Theta: np.ndarray, delay: int,
                           keep: np.ndarray) -> float:
    """VAF (%) of ``y(t)`` predicted by ``Phi(t)^T Theta(t - delay)``, pooled over records, on ``keep``.

    The EWLS estimate at ``t - delay`` was formed from data up to then only (it is causal); with
    ``delay`` beyond the filters' memory it has not seen the noise of the sample it predicts: a
    held-out prediction, unlike the fitted ``Phi(t)^T Theta(t)``.
    """
    yhat = np.einsum("rni,ni->rn", Phi[:, delay:], Theta[:len(Theta) - delay])
    k = keep[delay:]
    yy = y[:, delay:][:, k]
    return vaf(yy, yhat[:, k], undefined="nan")


def pointwise_bands(Phi: np.ndarray, y: np.ndarray, Theta: np.ndarray, dt: float, lam: float, delay: int,
                    steady: np.ndarray, level: float, R0: np.ndarray, m0: int):
    """Pointwise ``level`` bands of I(t), B(t), K(t) (and the stiffness, K) from :func:`ewls_variances`,
    normal quantiles. They describe the noise in the estimate, not its tracking lag (about ``1/lam``
    behind a changing parameter) or the bias of the filters."""

    from jointbench.core.estimate import Intervals

    z = z_quantile(level)
    se = np.sqrt(np.maximum(ewls_variances(Phi, y, Theta, dt, lam, delay, steady, R0, m0), 0.0))
    bounds = {k: (Theta[:, i] - z * se[:, i], Theta[:, i] + z * se[:, i]) for i, k in enumerate("IBK")}
    bounds["stiffness"] = bounds["K"]
    return Intervals(level=level, method="EWLS sandwich covariance with the held-out residuals' autocovariance "
                                         "(noise only, not the tracking lag, nor the filters' start-up bias on "
                                         "the samples outside the steady span)", bounds=bounds)


def forgetting_table(Phi: np.ndarray, y: np.ndarray, R0: np.ndarray, r0: np.ndarray, dt: float, grid, delay: int,
                     keep: np.ndarray, ewls) -> dict[float, float]:
    """``{lam: VAF}``: the held-out prediction VAF (:func:`delayed_prediction_vaf`) of the EWLS estimate
    (``ewls(Phi, y, dt, lam, R0, r0)``) for each forgetting rate ``lam`` of ``grid``.

    The causal estimate at ``t - delay`` has not seen the noise at ``t`` (``delay`` beyond the filters'
    memory), so a faster forgetting that follows the noise is penalised and a slower one that lags behind
    the parameters is too. On the Xu & Hollerbach elbow (K = 40 +- 15 N m/rad, PRBS, torque noise) with
    ``delay = 2/a`` the best rates are 20 1/s at 0.5 Hz and 30 1/s at 1 Hz, the rates with the best VAFV of
    K; at 1.5 Hz, where no rate tracks K, slow forgetting (the mean) wins.
    """
    return {lam: delayed_prediction_vaf(Phi, y, ewls(Phi, y, dt, lam, R0, r0), delay, keep) for lam in grid}
