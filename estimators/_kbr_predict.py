"""The prediction of the kernel-based regression estimator (:mod:`estimators.kbr`): the periodic solution
of the fitted time-varying differential equation, by a restarted GMRES.

References
----------
van de Ruit, M. et al. (2018). Revealing time-varying joint impedance with kernel-based regression
and nonparametric decomposition. IEEE Trans. Control Syst. Technol. 28(1), 224-237,
doi:10.1109/TCST.2018.2881664, eqs. 9 and 17.

Saad, Y. & Schultz, M. H. (1986). GMRES: a generalized minimal residual algorithm for solving
nonsymmetric linear systems. SIAM J. Sci. Stat. Comput. 7(3), 856-869.
"""
from __future__ import annotations

import math

import numpy as np
import scipy.linalg


# -------------------------------------------------------------------------------------- prediction
def periodic_derivative_response(n: int, fs: float, orders: int) -> np.ndarray:
    """``(j w_k)^n`` on the ``rfft`` bins (Nyquist bin zero for odd ``n``): exact for periodic records."""
    jw = 2j * np.pi * np.fft.rfftfreq(n, 1.0 / fs)
    D = np.stack([jw ** k for k in range(orders + 1)])
    if n % 2 == 0:
        D[1::2, -1] = 0.0
    return D


#: longest record whose periodic solution may fall back on a dense solve (an n x n matrix, 128 MiB)
DENSE_LIMIT = 4096


def gmres(operator, b: np.ndarray, restart: int, restarts: int, rtol: float,
          x0: np.ndarray | None = None, stall: float = 0.5) -> tuple[np.ndarray, bool]:
    """Restarted GMRES for a real ``n``-vector: ``x`` with ``||b - operator(x)|| <= rtol ||b||``.

    Arnoldi with classical Gram-Schmidt applied twice (each pass one product with the basis), the
    least-squares problem of the Hessenberg matrix by Givens rotations; at most ``restarts`` cycles of
    ``restart`` steps, each starting from the true residual; it gives up early when a cycle leaves more
    than ``stall`` of the residual it started from (a stagnating restarted GMRES; on the periodic
    solutions of :func:`periodic_response` the converging cycles leave at most 1.3e-3, the
    stagnating ones 0.8 ... 1). A preconditioner is folded into ``operator`` by the caller (right
    preconditioning: the residual is that of the original system). Returns ``x`` and whether it
    converged.

    References
    ----------
    Saad, Y. & Schultz, M. H. (1986). GMRES: a generalized minimal residual algorithm for solving
    nonsymmetric linear systems. SIAM J. Sci. Stat. Comput. 7(3), 856-869 (Algorithm 4);
    Giraud, L., Langou, J. & Rozloznik, M. (2005). The loss of orthogonality in the Gram-Schmidt
    orthogonalization process. Comput. Math. Appl. 50, 1069-1075 (twice is enough).
    """
    n = len(b)
    x = np.zeros(n) if x0 is None else np.array(x0, float)
    target = rtol * np.linalg.norm(b)
    V = np.empty((restart + 1, n))
    H = np.zeros((restart + 1, restart))
    previous = math.inf
    for _ in range(restarts):
        res = b - operator(x) if x.any() else b.copy()
        beta = float(np.linalg.norm(res))
        if beta <= target:
            return x, True
        if beta > stall * previous:
            return x, False
        previous = beta
        V[0] = res / beta
        g = [0.0] * (restart + 1)
        g[0] = beta
        cs, sn = [], []
        for j in range(restart):
            w = operator(V[j])
            h = V[:j + 1] @ w
            w -= h @ V[:j + 1]
            h2 = V[:j + 1] @ w
            w -= h2 @ V[:j + 1]
            hn = float(np.linalg.norm(w))
            if hn > 0:
                V[j + 1] = w / hn
            col = (h + h2).tolist() + [hn]
            for k in range(j):                    # the earlier rotations on the new column
                col[k], col[k + 1] = cs[k] * col[k] + sn[k] * col[k + 1], cs[k] * col[k + 1] - sn[k] * col[k]
            rho = math.hypot(col[j], hn)
            c, s = (col[j] / rho, hn / rho) if rho > 0 else (1.0, 0.0)
            cs.append(c)
            sn.append(s)
            col[j], col[j + 1] = rho, 0.0
            H[:j + 2, j] = col
            g[j], g[j + 1] = c * g[j], -s * g[j]
            if abs(g[j + 1]) <= target or hn == 0:
                break
        y = scipy.linalg.solve_triangular(H[:j + 1, :j + 1], g[:j + 1], check_finite=False)
        x = x + y @ V[:j + 1]
    res = np.linalg.norm(b - operator(x))
    return x, bool(res <= target)


def periodic_response(a: np.ndarray, r: np.ndarray, Dp: np.ndarray) -> np.ndarray:
    """Periodic solution ``y`` of ``y + sum_n a_n(t) y^(n) = r(t)`` on the record.

    Derivatives of ``y`` are the exact ones of a periodic band-limited signal (``Dp``, from
    :func:`periodic_derivative_response`). Solved by :func:`gmres` (restarted
    every 50 steps), right preconditioned with the time-invariant operator of the mean coefficients,
    which is diagonal in the DFT domain: ``y = M v``, and each step takes one ``rfft`` of ``v`` and one
    ``irfft`` of ``y`` and its derivatives. If it stalls short of 1e-12: a dense solve for records of at most
    :data:`DENSE_LIMIT` samples (128 MiB); longer records continue with restarts every 200 steps (200
    vectors of the record's length) and keep the solution when its relative residual is below 1e-2
    (a VAF then moves by hundredths of a point), else ``ValueError``.
    """
    n = len(r)
    na = len(a)
    if na == 0:
        return r.copy()
    den = Dp[0] + np.tensordot(a.mean(axis=1), Dp[1:na + 1], axes=1)
    den = np.where(np.abs(den) > 1e-12, den, 1e-12)
    Dm = np.vstack([Dp[:1], Dp[1:na + 1]]) / den        # y = M v and its derivatives, from the DFT of v

    def operator(v):                               # (I + sum_n a_n D_n) M v
        yd = np.fft.irfft(np.fft.rfft(v) * Dm, n, axis=1)
        return yd[0] + np.sum(a * yd[1:], axis=0)

    v, ok = gmres(operator, r, restart=50, restarts=20, rtol=1e-12)
    if not ok:
        if n <= DENSE_LIMIT:
            L = np.eye(n)
            for an, c in zip(a, np.fft.irfft(Dp[1:na + 1], n, axis=1)):
                L += an[:, None] * scipy.linalg.circulant(c)   # column j of D_n: the response to sample j
            return np.linalg.solve(L, r)
        # long records: never an n x n matrix (74.5 GiB at 100 000 samples); a longer Krylov basis instead
        # (fitted coefficients that change sign stall GMRES(50)). It may stagnate near 1e-3 at high rates,
        # which moves a VAF by about 0.01 point (19.67 against 19.66 % at 2.5e-3 on a 2.5 kHz wrist)
        v, ok = gmres(operator, r, restart=200, restarts=5, rtol=1e-12, x0=v)
        rel = float(np.linalg.norm(operator(v) - r) / max(np.linalg.norm(r), 1e-300))
        if not ok and not rel <= 1e-2:
            raise ValueError(f"the periodic solution of the fitted equation did not converge (relative residual "
                             f"{rel:.2g} after {20 * 50 + 5 * 200} GMRES steps on {n} samples); the fitted "
                             f"equation may be unstable: decimate towards the band of interest (e.g. 44 Hz)")
    return np.fft.irfft(np.fft.rfft(v) * Dm[0], n)
