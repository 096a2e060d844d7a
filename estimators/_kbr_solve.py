"""Numerical pieces of the kernel-based regression estimator (:mod:`estimators.kbr`).

Everything here is a pure function of arrays; :mod:`estimators.kbr` holds the settings, the checks
and the result object. The notation follows van de Ruit et al. (2018), Sec. III and App. B:

* ``D_n x``: ``n``-th derivative of a sampled signal ``x`` by a band-limited differentiator
  (:func:`differentiators`), ``n = 0 ... max(Na, Nb)``;
* the equation error of eq. 9, ``e = D_0 y + sum_n a_n D_n y - sum_n b_n D_n u``, kept only where the
  differentiators are exact (``mask``), and its DFT ``E(k)`` on the bins of the band of interest;
* each coefficient ``c_p(t) = c_p + g_p (Phi z_p)(t)``: a constant plus a time-varying part in the
  range of the kernel matrix ``K_p = g_p^2 K_0``, ``Phi Phi^T = K_0`` (:func:`kernel_features`), so
  that the regulariser ``check_p^T K_p^-1 check_p`` of eq. B.1 equals ``||z_p||^2``.

References
----------
van de Ruit, M. et al. (2018). Revealing time-varying joint impedance with kernel-based regression
and nonparametric decomposition. IEEE Trans. Control Syst. Technol. 28(1), 224-237,
doi:10.1109/TCST.2018.2881664, eqs. 9, 10, 15 and B.1-B.2.

Lataire, J., Pintelon, R., Piga, D. & Toth, R. (2017). Continuous-time linear time-varying system
identification with a frequency-domain kernel-based estimator. IET Control Theory Appl. 11(4), 457-465.
"""
from __future__ import annotations

import dataclasses
import functools

import numpy as np
import scipy.linalg
from scipy.linalg import lapack
from scipy import signal as sps


# ------------------------------------------------------------------------------------ derivatives
def differentiators(n: int, fs: float, f_pass: float, orders: int,
                    attenuation_db: float) -> tuple[np.ndarray, int]:
    """Frequency responses ``D_n(w_k) = (j w_k)^n G(w_k)`` on the ``rfft`` bins of an ``n``-point record.

    ``G`` is the response of a Kaiser-window low-pass FIR filter (:func:`scipy.signal.kaiserord`,
    :func:`scipy.signal.firwin`) with pass band up to ``f_pass`` and stop band from the Nyquist
    frequency, ``attenuation_db`` deep. Applied by FFT the filters act as circular convolutions whose
    impulse responses are negligible (below about ``10^(-attenuation_db/20)`` relative) beyond
    ``half`` samples, so on a record that is not periodic the derivatives are exact except within
    ``half`` samples of either end, which the estimator discards. All orders share ``G``, so the
    equation error of exact derivatives is only filtered by ``G``, which is 1 (to the ripple) in the
    band of interest.

    The odd orders' Nyquist discontinuity of ``(j w)^n`` is scaled by ``G`` at the Nyquist frequency
    (the stop band), which sets the slowly decaying part of their tails (about 1e-5 relative at
    ``half`` samples for 100 dB).

    Parameters
    ----------
    n : int
        Record length (samples).
    fs : float
        Sampling rate (Hz).
    f_pass : float
        Pass band edge (Hz), below ``fs / 2``.
    orders : int
        Highest derivative order.
    attenuation_db : float
        Stop band attenuation (dB) of the Kaiser design.

    Returns
    -------
    D : ndarray, shape (orders + 1, n // 2 + 1)
        Complex responses (units s^-n); the Nyquist bin is zero.
    half : int
        Half length of the FIR low-pass (samples): the number of samples to discard at each end.

    References
    ----------
    van de Ruit et al. (2018), App. B: ``u^(n)``, ``y^(n)`` in eq. B.2 are "the sampled and vectorised
    n-th derivatives"; how to obtain them from a record that is not periodic is this module's choice.
    """
    width = (fs / 2 - f_pass) / (fs / 2)
    numtaps, beta = sps.kaiserord(attenuation_db, width)
    numtaps |= 1
    half = numtaps // 2
    if 2 * half + 1 > n:
        raise ValueError(f"differentiator of {numtaps} taps is longer than the record ({n} samples)")
    taps = sps.firwin(numtaps, (f_pass + fs / 2) / 2, window=("kaiser", beta), fs=fs)
    circ = np.zeros(n)
    circ[:half + 1] = taps[half:]
    circ[n - half:] = taps[:half]
    G = np.fft.rfft(circ).real  # even taps: real response
    jw = 2j * np.pi * np.fft.rfftfreq(n, 1.0 / fs)
    D = np.stack([jw ** k * G for k in range(orders + 1)])
    if n % 2 == 0:
        D[:, -1] = 0.0
    return D, half


def derivatives(x: np.ndarray, D: np.ndarray) -> np.ndarray:
    """``D_n x`` for every row of ``D`` (shape ``(len(D), len(x))``)."""
    return np.fft.irfft(np.fft.rfft(x)[None, :] * D, len(x), axis=1)


# ----------------------------------------------------------------------------------------- kernel
def kernel_features(time: np.ndarray, sigma: float, threshold: float, max_rank: int, points: int) -> np.ndarray:
    """Features ``Phi`` (``N x r``) with ``Phi Phi^T ~ K_0``, ``K_0(t, t') = exp(-(t - t')^2 / sigma^2)``.

    The eigenpairs ``(lambda_j, w_j)`` of the kernel on ``points`` equispaced times spanning the record
    (the Nystrom method) give ``Phi = K(t, s) W_r Lambda_r^(-1/2)``; ``r`` keeps the eigenvalues at
    least ``threshold`` times the largest, at most ``max_rank``. When ``points`` equals the number of
    samples the times are the samples themselves and ``Phi = V_r Lambda_r^(1/2)``: the exact leading
    eigenpairs of the kernel matrix (the implementation note of the study spec). With
    ``a = sqrt(gamma) Phi z`` the regulariser ``a^T K^-1 a`` of ``K = gamma K_0`` over the range of
    ``K`` equals ``||z||^2``; ``K^-1`` is never formed.

    References
    ----------
    van de Ruit et al. (2018), eq. 15 (the kernel) and App. B ("does not require the explicit
    computation of K^-1").
    """
    t = np.asarray(time, float)
    s = t if points >= len(t) else np.linspace(t[0], t[-1], points)
    Kss = np.exp(-((s[:, None] - s[None, :]) / sigma) ** 2)
    lam, W = np.linalg.eigh(Kss)
    lam, W = lam[::-1], W[:, ::-1]
    r = int(min(max_rank, np.count_nonzero(lam >= threshold * lam[0])))
    lam, W = lam[:r], W[:, :r]
    if s is t:
        return W * np.sqrt(lam)
    Kts = np.exp(-((t[:, None] - s[None, :]) / sigma) ** 2)
    return (Kts @ W) / np.sqrt(lam)


# ---------------------------------------------------------------------------------- equation error
@dataclasses.dataclass(frozen=True)
class System:
    """The band-limited equation error, linear in the unknowns: ``E = F0 + C c + sum_p T_p z_p``.

    Coefficient ``p`` is ``c_p + g_p Phi z_p`` (``g_p = sqrt(gamma_p)``).

    Attributes
    ----------
    F0 : ndarray, complex (nk,)
        DFT on the band of ``mask * D_0 y``.
    C : ndarray, complex (nk, P)
        DFT on the band of ``mask * x_p``: regressor ``x_p = D_n y`` for ``a_n``, ``-D_n u`` for ``b_n``.
    T : ndarray, complex (P, nk, r)
        DFT on the band of ``mask * x_p * g_p * Phi[:, j]``.
    Phi : ndarray (N, r)
        Kernel features of ``K_0``.
    gains : ndarray (P,)
        ``g_p``.
    """

    F0: np.ndarray
    C: np.ndarray
    T: np.ndarray
    Phi: np.ndarray
    gains: np.ndarray

    def trajectories(self, c: np.ndarray, z: np.ndarray) -> np.ndarray:
        """Coefficients ``c_p + g_p Phi z_p`` on the samples (``P x N``)."""
        return c[:, None] + self.gains[:, None] * (z @ self.Phi.T)

    @functools.cached_property
    def rows(self) -> np.ndarray:
        """``[C T_1 ... T_P]^T`` (``(P + P r) x nk``, complex): ``E = F0 + x @ rows`` for ``x = [c, z]``."""
        P, nk, r = self.T.shape
        return np.ascontiguousarray(np.concatenate([self.C, self.T.transpose(1, 0, 2).reshape(nk, P * r)], axis=1).T)


def equation_system(regressors: np.ndarray, y0: np.ndarray, mask: np.ndarray, Phi: np.ndarray,
                    gains: np.ndarray, band: np.ndarray) -> System:
    """Assemble :class:`System` with one ``rfft`` of an ``N x r`` matrix per coefficient.

    Parameters
    ----------
    regressors : ndarray (P, N)
        ``x_p`` (``D_n y`` for the ``a_n``, ``-D_n u`` for the ``b_n``).
    y0 : ndarray (N,)
        ``D_0 y``.
    mask : ndarray (N,)
        1 where the derivatives are exact, 0 at the discarded ends.
    Phi : ndarray (N, r)
        Kernel features of ``K_0`` (:func:`kernel_features`).
    gains : ndarray (P,)
        ``sqrt(gamma_p)``: coefficient ``p`` has the kernel ``gamma_p K_0``.
    band : ndarray of int
        ``rfft`` bins of the band of interest.
    """
    X = regressors * mask
    F0 = np.fft.rfft(y0 * mask)[band]
    C = np.fft.rfft(X, axis=1)[:, band].T
    T = np.stack([g * np.fft.rfft(x[:, None] * Phi, axis=0)[band] for x, g in zip(X, gains)])
    return System(F0=F0, C=C, T=T, Phi=Phi, gains=np.asarray(gains, float))


def r_factor(A: np.ndarray) -> np.ndarray:
    """The R factor of a Householder QR of ``A`` (LAPACK ``geqrf``): its first ``min(M, N)`` rows.

    The same factorization as ``scipy.linalg.qr(A, mode='r')``, whose ``M x N`` result is zero below
    row ``N``: the rows below are not formed (for the tall systems here, most of the matrix), and ``A``,
    a temporary of the caller, is factorized in place."""
    return scipy.linalg.qr(A, mode="raw", overwrite_a=True, check_finite=False)[1]


def ridge_solve(Ac: np.ndarray, Az: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Minimise ``||Ac c + Az z - b||^2 + ||z||^2`` over ``c`` (free) and ``z`` (real arrays).

    :func:`ridge_solve_stacked` of ``[Ac Az b]``: the normal equations when they are well conditioned,
    else :func:`ridge_solve_qr`.
    """
    x = ridge_solve_stacked(np.column_stack([Ac, Az, b]), Ac.shape[1])
    return x[:Ac.shape[1]], x[Ac.shape[1]:]


#: least reciprocal condition number (LAPACK ``dpocon`` estimate) of the scaled normal matrix that
#: :func:`ridge_solve_stacked` solves by Cholesky; below it, the QR of :func:`ridge_solve_qr`
NORMAL_RCOND = 1e-10


def ridge_solve_stacked(W: np.ndarray, p: int) -> np.ndarray:
    """``x = [c, z]`` minimising ``||A x - b||^2 + ||z||^2``; ``W = [A b]``, ``c`` the first ``p`` unknowns.

    The normal equations ``(A^T A + diag(0, I)) x = A^T b``, scaled to a unit diagonal, are solved by
    Cholesky, followed by one step of iterative refinement with the residual ``b - A x`` computed
    from ``A`` itself. When ``kappa eps << 1`` (``kappa`` the condition number of the scaled normal
    matrix) the refined solution is as accurate as a Householder QR's: the refinement removes the
    ``kappa eps`` error of the Cholesky solve, and what remains is the rounding of the residual,
    which reaches ``x`` through ``A^T`` and so is amplified by ``sqrt(kappa)`` only. One product
    ``W^T W`` replaces a QR of the tall matrix (about 8 times faster at 1538 x 73). If the estimated
    ``kappa`` exceeds ``1 / NORMAL_RCOND`` (or Cholesky fails) the QR of :func:`ridge_solve_qr` is used.

    References
    ----------
    Bjorck, A. (1996). Numerical Methods for Least Squares Problems, SIAM, Sec. 2.9 (iterative
    refinement of least squares solutions); Higham, N. J. (2002). Accuracy and Stability of Numerical
    Algorithms, 2nd ed., SIAM, Sec. 20.5.
    """
    n = W.shape[1] - 1
    A, b = W[:, :n], W[:, n]
    G = W.T @ W
    ridge = np.zeros(n)
    ridge[p:] = 1.0
    d = np.sqrt(np.diag(G)[:n] + ridge)
    d[d == 0] = 1.0
    H = G[:n, :n] / np.outer(d, d)
    H[np.diag_indices(n)] += ridge / d ** 2
    norm1 = np.abs(H).sum(axis=0).max()
    R, info = lapack.dpotrf(H.T, lower=0, clean=0, overwrite_a=1)     # H.T: the symmetric H in Fortran order
    if info == 0:
        rcond, info = lapack.dpocon(R, norm1)
    if info != 0 or not rcond >= NORMAL_RCOND:
        c, z = ridge_solve_qr(W[:, :p], W[:, p:n], b)
        return np.concatenate([c, z])
    x = lapack.dpotrs(R, G[:n, n] / d, lower=0)[0] / d
    res = b - A @ x
    grad = A.T @ res - ridge * x
    return x + lapack.dpotrs(R, grad / d, lower=0)[0] / d


def ridge_solve_qr(Ac: np.ndarray, Az: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`ridge_solve` by QR, for any conditioning.

    One Householder QR (R factor only) of ``[Ac Az b]`` gives ``R11 c + R12 z ~ r1`` and the part
    orthogonal to ``range(Ac)``, ``R22 z ~ r2``: the unregularised ``c`` is eliminated exactly. Then
    ``z`` minimises ``||R22 z - r2||^2 + ||z||^2`` by a small QR of ``[R22; I]`` and
    ``c = R11^-1 (r1 - R12 z)``. No normal equations are formed (the weights can span many decades),
    and eliminating ``c`` keeps the near-collinearity of the constants with the smoothest kernel
    feature out of the solve.
    """
    p, q = Ac.shape[1], Az.shape[1]
    scale = np.linalg.norm(Ac, axis=0)
    scale[scale == 0] = 1.0
    R = r_factor(np.column_stack([Ac / scale, Az, b]))
    R11, R12, r1 = R[:p, :p], R[:p, p:p + q], R[:p, -1]
    R22, r2 = R[p:p + q, p:p + q], R[p:p + q, -1]
    if R22.shape[0] < q:                          # fewer equations than unknowns: pad with zero rows
        R22 = np.vstack([R22, np.zeros((q - R22.shape[0], q))])
        r2 = np.concatenate([r2, np.zeros(q - len(r2))])
    Rz = r_factor(np.vstack([np.column_stack([R22, r2]), np.column_stack([np.eye(q), np.zeros(q)])]))
    z = scipy.linalg.solve_triangular(Rz[:q, :q], Rz[:q, -1], check_finite=False)
    c = scipy.linalg.solve_triangular(R11, r1 - R12 @ z, check_finite=False) / scale
    return c, z


def solve_weighted(system: System, weights: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """Minimise ``sum_k w_k |E(k)|^2 + sum_p ||z_p||^2``: one step of the convex relaxation (App. B).

    The real and imaginary parts of each weighted equation are two real equations (interleaved rows of
    the float view of the complex rows), solved by :func:`ridge_solve_stacked`.

    Returns
    -------
    c : ndarray (P,)
        Constant parts.
    z : ndarray (P, r)
        Weights of the kernel features.
    cost : float
        The minimised cost.

    References
    ----------
    van de Ruit et al. (2018), eq. B.1 with ``sigma_E^2`` fixed (the convex relaxation of App. B).
    """
    P, nk, r = system.T.shape
    nu = P + P * r
    sw = np.sqrt(weights)
    Wt = np.empty((nu + 1, nk), complex)
    np.multiply(system.rows, sw, out=Wt[:nu])
    np.multiply(system.F0, -sw, out=Wt[nu])
    W = Wt.view(float).T
    x = ridge_solve_stacked(W, P)
    res = W[:, :nu] @ x - W[:, nu]
    return x[:P], x[P:].reshape(P, r), float(res @ res + x[P:] @ x[P:])


#: most halvings of a Gauss-Newton step in :func:`step_length` before :func:`refine` gives up: the step is
#: then 2^-30 (about 1e-9) of the Gauss-Newton step, and a direction that does not lower the cost that close
#: to the current point is not a descent direction at working precision (the fits of tests/test_kbr.py
#: halve at most twice)
MAX_HALVINGS = 30
#: the longest step :func:`step_length` tries, in Gauss-Newton steps: it doubles the step while the cost keeps
#: falling (long curved valleys), up to this bound on how far the linearisation is trusted (the fits of
#: tests/test_kbr.py go to 8 at most)
MAX_STEP = 64.0


class B1Cost:
    """Eq. B.1 itself, ``sum_k |E(k)|^2 / sigma_E^2(k, a) + sum ||z||^2``, as a function of ``x = [c, z]``.

    ``sigma_E^2(k, a) = sv2(k) q_k(a)``, ``q_k = mean_t |A(k, t)|^2``, ``A(k, t) = D_0(k) + sum_n
    a_n(t) D_n(k)`` over the kept samples (``Db``: band rows of the responses of orders ``0 ... Na``;
    ``a_n`` are the first ``Na`` coefficients). The arrays every evaluation shares are formed once here.

    Parameters
    ----------
    system : System
        The equation error of the fit.
    Db : ndarray, complex (Na + 1, nk)
        Band rows of the differentiator responses of orders ``0 ... Na``.
    mask : ndarray (N,)
        1 on the kept samples.
    sv2 : ndarray (nk,)
        ``(N_kept / N) sigma_V^2(k)`` on the band.

    References
    ----------
    van de Ruit et al. (2018), eqs. 10 and B.1; App. B for ``sigma_E^2`` depending on the coefficients.
    """

    def __init__(self, system: System, Db: np.ndarray, mask: np.ndarray, sv2: np.ndarray):
        self.system, self.Db, self.sv2 = system, Db, sv2
        self.na = len(Db) - 1
        self.P, self.nk, self.r = system.T.shape
        self.nu = self.P + self.P * self.r
        self.Pk = system.Phi[mask > 0]
        self.nt = self.Pk.shape[0]
        self.m = self.Pk.mean(axis=0)
        self.rows = system.rows
        self.Dn = Db[1:]                                   # (na, nk): D_1 ... D_Na
        # A depends on the c_n and z_n of the a_n (n < na): the first na unknowns and the na r from P
        self.DnR, self.DnI = np.ascontiguousarray(self.Dn.real), np.ascontiguousarray(self.Dn.imag)
        self.gm = system.gains[:self.na, None] * self.m[None, :]
        # q_k = sum_ij M_ij Re(conj(D_i(k)) D_j(k)) for the second moments M of (1, a_1(t), ..., a_Na(t))
        self.DD = (Db.conj()[:, None, :] * Db[None, :, :]).real.reshape((self.na + 1) ** 2, self.nk)

    def denominators(self, x: np.ndarray) -> np.ndarray:
        """``a_n(t)`` on the kept samples for the unknowns ``x`` (``Na x N_kept``)."""
        na, P, r = self.na, self.P, self.r
        return x[:na, None] + self.system.gains[:na, None] * (x[P:P + na * r].reshape(na, r) @ self.Pk.T)

    def parts(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
        """``a_n(t)``, ``q_k``, ``E(k)`` and the cost at ``x``."""
        a = self.denominators(x)
        basis = np.vstack([np.ones(self.nt), a])
        q = (basis @ basis.T / self.nt).ravel() @ self.DD
        E = self.system.F0 + x @ self.rows
        P = self.P
        return a, q, E, float(np.sum((E.real ** 2 + E.imag ** 2) / (self.sv2 * q)) + x[P:] @ x[P:])

    def along(self, a: np.ndarray, q: np.ndarray, E: np.ndarray, x: np.ndarray, dx: np.ndarray):
        """The cost at ``x + s dx`` as a function of ``s`` (``a, q, E`` of :meth:`parts` at ``x``): ``E`` is
        affine in ``s``, ``q`` quadratic."""
        nt, DD, sv2, P = self.nt, self.DD, self.sv2, self.P
        dE = dx @ self.rows
        da = self.denominators(dx)
        basis, dbasis = np.vstack([np.ones(nt), a]), np.vstack([np.zeros(nt), da])
        M1 = basis @ dbasis.T / nt
        q1 = (M1 + M1.T).ravel() @ DD
        q2 = (dbasis @ dbasis.T / nt).ravel() @ DD
        z, dz = x[P:], dx[P:]

        def cost(s):
            Es = E + s * dE
            return float(np.sum((Es.real ** 2 + Es.imag ** 2) / (sv2 * (q + s * (q1 + s * q2))))
                         + (z + s * dz) @ (z + s * dz))
        return cost

    def linearise(self, x: np.ndarray, a: np.ndarray, q: np.ndarray, E: np.ndarray, Jt: np.ndarray) -> None:
        """The Gauss-Newton model at ``x`` into ``Jt`` (complex, ``(nu + 1) x nk``): the Jacobian of the
        rotated, whitened residuals (rows ``0 ... nu - 1``) and the right-hand side ``J x - w`` (row ``nu``)
        whose least-squares solution is the next ``x``. The real and imaginary parts of each bin are two
        equations, interleaved in the float view.

        The residuals are rotated by the unit phase ``phi = conj(Abar)/|Abar|`` (``Abar = mean_t A``), which
        leaves the cost unchanged: for a time-invariant ``A`` this is the output error
        ``(Y - B/A U)/sqrt(sv2)``, so bins without input carry no spurious curvature into the model.
        """
        na, P, r, nu, nt, Dn = self.na, self.P, self.r, self.nu, self.nt, self.Dn
        g = self.system.gains
        Jv = Jt.view(float).reshape(nu + 1, self.nk, 2)   # (real, imaginary) of each entry
        Abar = self.Db[0] + (a.mean(axis=1) @ Dn if na else 0.0)
        absA = np.maximum(np.abs(Abar), 1e-300)
        phi = Abar.conj() / absA
        sd = np.sqrt(self.sv2 * q)
        w = E * phi / sd                          # the rotated, whitened residuals
        # J = (phi CT + E dphi - E phi dq / (2 q)) / sd. The last two terms only touch the columns of the
        # a_n, where with w = E phi / sd they are -w (dq / (2 q) + 1j Im(phi dAbar) / |Abar|):
        # dq/dc_n = 2 Re(conj(Abar) D_n) = 2 |Abar| Re(phi D_n), dq/dz_nj = 2 g_n Re(D_n conj(mean_t A Phi_j)),
        # Im(phi dAbar/dz_nj) = g_n mean_t Phi_j Im(phi D_n)
        np.multiply(self.rows, phi / sd, out=Jt[:nu])
        if na:
            APhi = np.outer(self.m, self.Db[0]) + (a @ self.Pk / nt).T @ Dn
            v = phi * Dn
            Xc = v.imag / absA
            Rc = v.real * (absA / q)
            Rz = (g[:na, None, None] / q) * (self.DnR[:, None, :] * APhi.real + self.DnI[:, None, :] * APhi.imag)
            Xz = self.gm[:, :, None] * Xc[:, None, :]
            wr, wi = w.real, w.imag
            Jc, Jz = Jv[:na], Jv[P:P + na * r].reshape(na, r, self.nk, 2)
            Jc[..., 0] -= wr * Rc - wi * Xc
            Jc[..., 1] -= wr * Xc + wi * Rc
            Jz[..., 0] -= wr * Rz - wi * Xz
            Jz[..., 1] -= wr * Xz + wi * Rz
        Jt[nu] = x @ Jt[:nu] - w


def step_length(cost_at, cost: float) -> float | None:
    """The step along a Gauss-Newton direction: 1, halved until the cost ``cost_at(step)`` is at most ``cost``
    (at most :data:`MAX_HALVINGS` times; None when it never is), or doubled while it keeps decreasing (long
    curved valleys, up to :data:`MAX_STEP`)."""
    step = 1.0
    for _ in range(MAX_HALVINGS):
        trial = cost_at(step)
        if trial <= cost:
            break
        step /= 2
    else:
        return None
    while step >= 1.0 and step < MAX_STEP:
        longer = cost_at(2 * step)
        if longer >= trial:
            break
        step, trial = 2 * step, longer
    return step


def refine(cost: B1Cost, c: np.ndarray, z: np.ndarray, iterations: int,
           tolerance: float) -> tuple[np.ndarray, np.ndarray, float, int]:
    """Gauss-Newton minimisation of eq. B.1 itself (:class:`B1Cost`) from the constants ``c`` and feature
    weights ``z``.

    Each step linearises the residuals ``E / sigma_E`` (the derivative of ``q_k`` included,
    :meth:`B1Cost.linearise`) and solves the linear ridge problem for the new ``(c, z)`` with
    :func:`ridge_solve_stacked`; the step along it is :func:`step_length`'s. Stops when the cost decreases
    by less than ``tolerance * max(cost, 1)``, when no step lowers it, or after ``iterations`` steps.

    Returns
    -------
    c, z : ndarray
        The refined constants and feature weights.
    cost : float
        Eq. B.1 at ``(c, z)``.
    steps : int
        Gauss-Newton steps taken.

    References
    ----------
    van de Ruit et al. (2018), eqs. 10 and B.1 (the estimator is their minimiser); App. B for
    ``sigma_E^2`` depending on the coefficients.
    """
    P, r = cost.P, cost.r
    x = np.concatenate([c, z.ravel()])
    a, q, E, value = cost.parts(x)
    Jt = np.empty((cost.nu + 1, cost.nk), complex)
    done = 0
    for done in range(1, iterations + 1):
        cost.linearise(x, a, q, E, Jt)
        dx = ridge_solve_stacked(Jt.view(float).T, P) - x
        step = step_length(cost.along(a, q, E, x, dx), value)
        if step is None:
            break
        x = x + step * dx
        previous = value
        a, q, E, value = cost.parts(x)
        if previous - value <= tolerance * max(value, 1.0):
            break
    return x[:P], x[P:].reshape(P, r), value, done
