"""Noise, uncertainty, model choice and memory of the kernel-based regression (:mod:`estimators.kbr`).

Pure functions: the output noise's variance at the band bins and how it enters the equation error (the
weights of the fit); on the :class:`estimators._kbr_solve.System` of a fit, the marginal likelihood of the
kernel's width and scale (for ``sigma``/``gamma = auto``), the posterior covariance of the coefficients
and the pointwise standard deviation of the stiffness; and the memory a fit plans to use.

References
----------
van de Ruit, M. et al. (2018). Revealing time-varying joint impedance with kernel-based regression
and nonparametric decomposition. IEEE Trans. Control Syst. Technol. 28(1), 224-237,
doi:10.1109/TCST.2018.2881664, eqs. 9, 15, 16 and B.1.
"""
from __future__ import annotations

import numpy as np

from jointbench.estimators._kbr_solve import System, r_factor
from jointbench.core.intervals import PINV_RCOND, psd_pinv


def _stack(x: np.ndarray) -> np.ndarray:
    """The real parts of ``x`` over its imaginary parts: each complex equation as two real ones."""
    return np.concatenate([x.real, x.imag])


def posterior(system: System, weights: np.ndarray) -> tuple[float, np.ndarray]:
    """``-2 log`` marginal likelihood of the kernel hyperparameters, and the covariance of ``[c, z]``.

    The weighted solve (:func:`solve_weighted`) minimises ``||A_c c + A_z z - b||^2 + ||z||^2`` over the
    real-stacked equations whitened by ``sqrt(weights)``; it is the posterior mode of the Gaussian
    model ``b = A_c c + A_z z + e`` with ``e ~ N(0, I/2)``, ``z ~ N(0, I/2)`` and a flat prior on ``c``.
    Integrating ``z`` out and ``c`` by restricted likelihood gives
    ``-2 log L = 2 cost + log det(I + A_z^T P A_z) + log det(A_c^T A_c) - 2 sum_k log w_k`` (``P`` the
    projection off ``range(A_c)``; the last term is the whitening's Jacobian, two rows per bin), up to a
    constant; smaller is better. The posterior covariance of ``[c, z]`` is ``(A^T A + diag(0, I))^-1 / 2``.

    References
    ----------
    Rasmussen, C. E. & Williams, C. K. I. (2006). Gaussian Processes for Machine Learning, MIT Press,
    eq. 5.8 (marginal likelihood); Patterson & Thompson (1971), Biometrika 58 (restricted likelihood).
    """
    P, nk, r = system.T.shape
    q = P * r
    sw = np.sqrt(weights)
    Ac = _stack(system.C * sw[:, None])
    Az = _stack(system.T.transpose(1, 0, 2).reshape(nk, q) * sw[:, None])
    b = _stack(-system.F0 * sw)
    scale = np.linalg.norm(Ac, axis=0)
    scale[scale == 0] = 1.0
    R = r_factor(np.column_stack([Ac / scale, Az, b]))
    R11 = R[:P, :P]
    R22 = R[P:P + q, P:P + q]
    r2 = R[P:P + q, -1]
    rho2 = float(np.sum(R[P + q:, -1] ** 2)) if R.shape[0] > P + q else 0.0
    if R22.shape[0] < q:
        R22 = np.vstack([R22, np.zeros((q - R22.shape[0], q))])
        r2 = np.concatenate([r2, np.zeros(q - len(r2))])
    Rz = r_factor(np.vstack([np.column_stack([R22, r2]), np.column_stack([np.eye(q), np.zeros(q)])]))
    cost = rho2 + float(Rz[q, q] ** 2) if Rz.shape[0] > q else rho2
    tiny = np.finfo(float).tiny
    neg2 = (2.0 * cost + 2.0 * np.sum(np.log(np.maximum(np.abs(np.diag(Rz[:q, :q])), tiny)))
            + 2.0 * np.sum(np.log(np.maximum(np.abs(np.diag(R11)) * scale, tiny)))
            - 2.0 * np.sum(np.log(np.maximum(weights, tiny))))
    A = np.column_stack([Ac, Az])
    M = A.T @ A
    M[P:, P:] += np.eye(q)
    return float(neg2), 0.5 * psd_pinv(M, PINV_RCOND)


def stiffness_sd(system: System, cov: np.ndarray, coef: np.ndarray, na: int, f1: float,
                 rows: np.ndarray) -> np.ndarray:
    """Posterior standard deviation of ``|H(j 2 pi f1, t)|`` at the samples ``rows`` (linearised).

    ``H = sum_n b_n s^n / (1 + sum_n a_n s^n)``; ``d|H| = Re(conj(H) dH) / |H|`` with
    ``dH/db_n = s^n / D`` and ``dH/da_n = -H s^n / D``; coefficient ``p`` is ``c_p + g_p Phi z_p``, so
    its derivative reaches ``c_p`` with weight 1 and ``z_p`` with ``g_p Phi(t)``.
    """
    s = 2j * np.pi * f1
    a, b = coef[:na, rows], coef[na:, rows]
    D = 1.0 + sum(a[n] * s ** (n + 1) for n in range(na))
    H = sum(b[n] * s ** n for n in range(len(b))) / D
    dH = np.vstack([-H * s ** (n + 1) / D for n in range(na)] + [s ** n / D + 0 * H for n in range(len(b))])
    mag = np.maximum(np.abs(H), 1e-300)
    G = (np.conj(H)[None, :] * dH).real / mag                               # (P, m)
    Phi = system.Phi[rows]                                                  # (m, r)
    J = np.hstack([G.T] + [(G[p] * system.gains[p])[:, None] * Phi for p in range(len(G))])
    return np.sqrt(np.maximum(np.sum((J @ cov) * J, axis=1), 0.0))


def memory_bytes(n: int, orders: int, P: int, points: int, r: int, nk: int, lines: int) -> int:
    """Bytes a fit of ``n`` samples needs, with its prediction and its tables.

    The sum of the arrays alive during the fit (``orders`` differentiator responses and derivatives,
    the ``P`` regressors, ``r`` kernel features on ``points`` times and their DFTs, the stacked
    equations of ``nk`` band bins and their QR) and after it (GMRES's 200 vectors for the periodic
    prediction, the frozen-response table of every sample and line, about 150 bytes a row with its
    temporaries). An upper bound within about a factor of two (100 000 samples, 25 lines: 475 MiB
    planned, 565 MB peak resident, the interpreter and libraries included).
    """
    floats = (n * (2 * orders + 2 * P + points + 3 * r)       # D, derivatives, Phi and its DFTs
              + points * points * 2                           # kernel eigenproblem
              + 2 * P * nk * r + 3 * 2 * nk * (P * r + P + 1)  # T; stacked equations and QR
              + 200 * n + (P + 3) * n)                        # GMRES(200); the estimate's table
    return int(8 * floats + 150 * n * lines)


# ------------------------------------------------------------------------------------------- noise
def noise_variance(Y: np.ndarray, lines: np.ndarray, band: np.ndarray, guard: int, count: int) -> np.ndarray:
    """Output noise variance ``E|V(k)|^2`` at the band bins from the non-excited bins.

    The mean of ``|Y(j)|^2`` over the ``count`` non-excited bins ``j`` nearest to ``k`` (ties to the
    lower bin), where bins within ``guard`` bins of an excited line (its skirt) and the DC and Nyquist
    bins are left out.

    References
    ----------
    van de Ruit et al. (2018), App. B: the noise variance of the measured spectra, there by their
    ref. [52] (Lataire & Pintelon 2009), here by this local average.
    """
    nb = len(Y)
    j = np.arange(1, nb - 1)
    dist = np.min(np.abs(j[:, None] - lines[None, :]), axis=1)
    j = j[dist > guard]
    if len(j) < count:
        raise ValueError(f"only {len(j)} non-excited bins are left for the noise estimate, {count} needed")
    pos = np.searchsorted(j, band)
    lo = np.clip(pos - count, 0, len(j) - 2 * count) if len(j) >= 2 * count else np.zeros_like(pos)
    cand = lo[:, None] + np.arange(min(2 * count, len(j)))[None, :]
    d = np.abs(j[cand] - band[:, None])
    nearest = np.take_along_axis(cand, np.argsort(d, axis=1, kind="stable")[:, :count], axis=1)
    return np.mean(np.abs(Y[j[nearest]]) ** 2, axis=1)


def error_variance_factor(D: np.ndarray, a: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """``mean_t |D_0(k) + sum_n a_n(t) D_n(k)|^2`` over the kept samples: how the output noise enters ``E``.

    ``D`` holds the band rows of the differentiator responses (orders ``0 ... Na``), ``a`` the
    trajectories ``a_1 ... a_Na`` (``Na x N``).
    """
    keep = mask > 0
    basis = np.vstack([np.ones(np.count_nonzero(keep)), a[:, keep]])
    M = basis @ basis.T / basis.shape[1]          # second moments of (1, a_1(t), ..., a_Na(t))
    return np.einsum("ik,ij,jk->k", D.conj(), M, D).real
