"""Symmetric eigendecomposition of stacks of small matrices, compiled, and the MDL pseudo-inverse on it.

Private module (the leading underscore keeps it out of the estimator registry) of
:func:`jointbench.estimators._tvirf.mdl_solve`, which imports it on first use: importing numba costs a
few tenths of a second, so ``import jointbench.estimators`` does not. numpy's ``linalg.eigh`` calls
LAPACK once per matrix, and for the thousands of 9 x 9 information matrices of an ensemble fit its cost
per call (about 5 us) was most of the fit (issue 22); here one compiled loop over the stack does the
eigendecomposition, the MDL order and the solution of every matrix. :func:`lagged_gram` forms the
matrices themselves for ``ensemble_irf`` from the products of samples up to ``L - 1`` apart (numpy's
batched product of the lagged input with itself was the next largest part of the fit).

The eigensolver is the textbook one (Golub & Van Loan, Matrix Computations, 4th ed., Sec. 8.3):
Householder reduction to tridiagonal form ``A = Q T Q^T`` with ``Q`` accumulated, then implicit
symmetric QR steps with the Wilkinson shift (a Givens rotation chasing the bulge down the band), the
rotations accumulated into ``Q``; an off-diagonal entry is taken as zero when it is below machine
epsilon times the two diagonal entries beside it (deflation). Both stages are backward stable: the
eigenvalues are those of ``A + E`` with ``||E|| ~ eps ||A||``, as with LAPACK (the solutions ``h`` of
an ill-conditioned system differ from numpy's by about eps times its condition number, as numpy's
differ from the exact ones: tests/test_small_eigh.py). Each matrix is first scaled by a power of two
(exact) to a largest entry near 1, so that no square over- or underflows. The matrices are decomposed
``B`` at a time, each step on all of them at once (the innermost axis of the work arrays): the QR
rotations of one matrix wait on each other, those of ``B`` matrices run side by side.

The kernels are compiled by numba in nopython mode on first use and cached on disk
(:mod:`jointbench.core.compiled`: how every compiled loop of the package is compiled and cached). The
solver pays for itself: with ``numpy.linalg.eigh`` instead, a cold ``jointbench run vanderuit2018_table2``
took about a quarter longer (issue 34, results/benchmarks.md).
"""
from __future__ import annotations

import math

import numpy as np

from jointbench.core.compiled import jit, jit_inline

#: QR steps allowed per eigenvalue before giving up (LAPACK's dsteqr allows 30 as well)
MAX_STEPS = 30
#: matrices decomposed together, each step done on all of them at once (the innermost axis of the work
#: arrays, so that it runs as vector instructions): a QR rotation waits on the previous one of its
#: matrix (a square root and a division), so one matrix at a time leaves the processor mostly idle.
#: 32 was the fastest of 8, 16, 32 and 64 on the 992 9 x 9 matrices of the ensemble benchmark.
B = 32
EPS = np.finfo(np.float64).eps
#: off-diagonal entries below this (of a matrix scaled to a largest entry in [0.5, 1)) are zero, and
#: rotations of a pair below TINY are skipped: far below rounding, and their squares would underflow
FLOOR, TINY = 1e-150, 1e-290


@jit
def _load(Phi, t0, A, unscale):
    """Matrices ``t0 ... t0 + B - 1`` of ``Phi`` into ``A[:, :, lane]`` (zero past the end), each scaled by
    a power of two (exact) to a largest entry in [0.5, 1); ``unscale[lane]`` undoes it."""
    T, n = Phi.shape[0], Phi.shape[1]
    for q in range(B):
        t = t0 + q
        top = 0.0
        if t < T:
            for i in range(n):
                for j in range(n):
                    top = max(top, abs(Phi[t, i, j]))
        ex = math.frexp(top)[1] if 0.0 < top < np.inf else 0
        scale = math.ldexp(1.0, -ex)
        unscale[q] = math.ldexp(1.0, ex)
        for i in range(n):
            for j in range(n):
                A[i, j, q] = Phi[t, i, j] * scale if t < T else 0.0


@jit
def _tridiagonalize(A, d, e, W, v, beta, p, s):
    """Householder reduction of each symmetric ``A[:, :, lane]`` (both triangles; overwritten) to the
    tridiagonal ``T = W A W^T``: ``d`` its diagonal, ``e[i] = T[i, i + 1]`` (``e[n - 1] = 0``), ``W``
    orthogonal (arrays ``(..., B)``, one lane a matrix).

    Reflector ``k`` is ``H_k = I - beta[k] v_k v_k^T`` with ``v_k = v[k, k+1:]``, chosen to map the column
    ``A[k+1:, k]`` onto its first axis; ``T = H_{n-3} ... H_0 A H_0 ... H_{n-3}``, so ``W = H_{n-3} ... H_0``.
    ``v`` (n, n, B), ``beta``, ``p`` (n, B) and ``s`` (3, B) are work space.
    """
    n, nl = A.shape[0], A.shape[2]             # nl: the lanes (B), a run-time count so that LLVM
    x0, sigma, half = s[0], s[1], s[2]         # vectorizes the lane loops instead of unrolling them
    for k in range(n - 2):
        # the column below the diagonal, read as the row A[k, k+1:] (A is kept symmetric)
        for q in range(nl):
            x0[q] = A[k, k + 1, q]
            sigma[q] = 0.0
        for j in range(k + 2, n):
            for q in range(nl):
                sigma[q] += A[k, j, q] * A[k, j, q]
                v[k, j, q] = A[k, j, q]
        for q in range(nl):
            # alpha = -sign(x0) |x|, so that v0 = x0 - alpha has no cancellation; a column already
            # tridiagonal (sigma = 0) is left alone (beta = 0: H = I)
            alpha = np.sqrt(x0[q] * x0[q] + sigma[q])
            alpha = -alpha if x0[q] > 0.0 else alpha
            v0 = x0[q] - alpha
            reflect = sigma[q] != 0.0
            e[k, q] = alpha if reflect else x0[q]
            beta[k, q] = 2.0 / (v0 * v0 + sigma[q]) if reflect else 0.0
            v[k, k + 1, q] = v0
            half[q] = 0.0
        # the trailing block C <- H C H = C - v w^T - w v^T, with p = beta C v, w = p - (beta/2)(v^T p) v
        for i in range(k + 1, n):
            for q in range(nl):
                p[i, q] = 0.0
            for j in range(k + 1, n):
                for q in range(nl):
                    p[i, q] += A[i, j, q] * v[k, j, q]
            for q in range(nl):
                p[i, q] *= beta[k, q]
                half[q] += v[k, i, q] * p[i, q]
        for i in range(k + 1, n):
            for q in range(nl):
                p[i, q] -= 0.5 * beta[k, q] * half[q] * v[k, i, q]
        for i in range(k + 1, n):
            for j in range(k + 1, n):
                for q in range(nl):
                    A[i, j, q] -= v[k, i, q] * p[j, q] + p[i, q] * v[k, j, q]
    for q in range(nl):
        for i in range(n):
            d[i, q] = A[i, i, q]
        if n >= 2:
            e[n - 2, q] = A[n - 2, n - 1, q]
        e[n - 1, q] = 0.0
    # W = H_{n-3} ... H_0, as W <- W H_k from the last reflector back: before H_k, W differs from the
    # identity only in its rows and columns k+2 ..., so W H_k changes rows and columns k+1 ... only
    for i in range(n):
        for j in range(n):
            for q in range(nl):
                W[i, j, q] = 1.0 if i == j else 0.0
    for k in range(n - 3, -1, -1):
        for i in range(k + 1, n):
            for q in range(nl):
                half[q] = 0.0
            for j in range(k + 1, n):
                for q in range(nl):
                    half[q] += W[i, j, q] * v[k, j, q]
            for j in range(k + 1, n):
                for q in range(nl):
                    W[i, j, q] -= beta[k, q] * half[q] * v[k, j, q]


@jit
def _split(d, e, i, q):
    """Whether ``e[i]`` of lane ``q`` is negligible: below rounding beside its diagonal neighbours."""
    return abs(e[i, q]) <= max(EPS * (abs(d[i, q]) + abs(d[i + 1, q])), FLOOR)


@jit
def _qr(d, e, W, iw, fw):
    """Eigenvalues of the tridiagonals ``(d, e)`` (one a lane) into ``d`` (unsorted), the rotations applied
    to the rows of ``W``; the lane that did not converge in ``MAX_STEPS`` steps per eigenvalue, or -1.

    Each pass finds every lane's lowest unreduced block ``lo ... hi`` (an off-diagonal is zero when
    ``|e[i]| <= eps (|d[i]| + |d[i+1]|)``, or below FLOOR) and makes one implicit QR step on it with the
    Wilkinson shift (Golub & Van Loan, Alg. 8.3.2): the rotation of the first column of ``T - mu I``,
    then the bulge it makes below the band chased down, one rotation per row. The lanes move together,
    each rotation a loop over them without branches (vector instructions): at row ``k`` a lane whose
    block does not hold ``k`` rotates by the identity, which leaves its values as they are. ``iw`` (3, B) int
    and ``fw`` (8, B) are work space.
    """
    n, nl = d.shape[0], d.shape[1]
    hi, lo, steps = iw[0], iw[1], iw[2]
    x, z, cs, sn = fw[0], fw[1], fw[2], fw[3]
    for q in range(nl):
        hi[q] = n - 1
        steps[q] = 0
    while True:
        kmin, kmax = n, 0
        for q in range(nl):
            h = hi[q]
            while h > 0 and _split(d, e, h - 1, q):
                e[h - 1, q] = 0.0                 # d[h] is an eigenvalue: deflate
                h -= 1
            hi[q] = h
            lo[q] = h
            if h == 0:
                continue
            l = h - 1
            while l > 0 and not _split(d, e, l - 1, q):
                l -= 1
            if l > 0:
                e[l - 1, q] = 0.0
            steps[q] += 1
            if steps[q] > MAX_STEPS * n:
                return q
            # Wilkinson shift: the eigenvalue of the block's trailing 2 x 2 nearer its last diagonal entry
            ta, tb, tc = d[h - 1, q], e[h - 1, q], d[h, q]
            delta = 0.5 * (ta - tc)
            root = np.sqrt(delta * delta + tb * tb)
            mu = tc - tb * tb / (delta + root if delta >= 0.0 else delta - root)
            lo[q] = l
            x[q], z[q] = d[l, q] - mu, e[l, q]
            kmin, kmax = min(kmin, l), max(kmax, h)
        if kmax == 0:
            return -1
        for k in range(kmin, kmax):
            km1 = max(k - 1, 0)
            for q in range(nl):
                on = (lo[q] <= k) & (k < hi[q])
                r = np.sqrt(x[q] * x[q] + z[q] * z[q])
                inv = 1.0 / r if on & (r > TINY) else 0.0
                c = x[q] * inv if inv != 0.0 else 1.0     # R = [[c, s], [-s, c]] takes (x, z) to (r, 0)
                s = z[q] * inv
                e[km1, q] = r if on & (k > lo[q]) else e[km1, q]   # the bulge T[k+1, k-1] into T[k, k-1]
                dk, ek, dk1 = d[k, q], e[k, q], d[k + 1, q]
                d[k, q] = c * c * dk + 2.0 * c * s * ek + s * s * dk1
                d[k + 1, q] = s * s * dk - 2.0 * c * s * ek + c * c * dk1
                e[k, q] = c * s * (dk1 - dk) + (c * c - s * s) * ek
                more = on & (k + 1 < hi[q])
                nxt = e[k + 1, q]
                z[q] = s * nxt if more else z[q]          # the new bulge T[k+2, k]
                e[k + 1, q] = c * nxt if more else nxt
                x[q] = e[k, q] if more else x[q]
                cs[q], sn[q] = c, s
            for i in range(n):                    # T <- R T R^T, so W <- R W on rows k, k+1
                for q in range(nl):
                    wk, wk1 = W[k, i, q], W[k + 1, i, q]
                    W[k, i, q] = cs[q] * wk + sn[q] * wk1
                    W[k + 1, i, q] = cs[q] * wk1 - sn[q] * wk


def _workspace(n):
    """The arrays :func:`_decompose` works in, for matrices of size n, allocated by the caller (a compiled
    allocation was one more function to compile): ``A, d, e, W, v, beta, p, fw, iw, unscale``."""
    return (np.empty((n, n, B)), np.empty((n, B)), np.empty((n, B)), np.empty((n, n, B)), np.empty((n, n, B)),
            np.empty((n, B)), np.empty((n, B)), np.empty((8, B)), np.empty((3, B), np.int64), np.empty(B))


@jit_inline
def _decompose(Phi, t0, ws):
    """Matrices ``t0 ... t0 + B - 1`` of ``Phi`` as ``Phi[t0 + q] = unscale[q] W^T diag(d) W`` in lane ``q``
    of the work arrays ``ws`` (eigenvalues unsorted, eigenvectors in the rows of ``W[:, :, q]``); the lane
    of a matrix that did not converge, or -1."""
    A, d, e, W, v, beta, p, fw, iw, unscale = ws
    _load(Phi, t0, A, unscale)
    _tridiagonalize(A, d, e, W, v, beta, p, fw)
    return _qr(d, e, W, iw, fw)


@jit
def _descending(d, q, idx):
    """``idx``: the indices of lane ``q`` of ``d`` by descending value (selection sort: n is small)."""
    n = d.shape[0]
    for i in range(n):
        idx[i] = i
    for i in range(n - 1):
        best = i
        for j in range(i + 1, n):
            if d[idx[j], q] > d[idx[best], q]:
                best = j
        idx[i], idx[best] = idx[best], idx[i]


@jit
def _eigh_stack(Phi, s, V, ws):
    """Eigenvalues (descending) and eigenvectors (columns) of every matrix of ``Phi`` (T, n, n) into ``s``
    and ``V`` (``ws``: :func:`_workspace`); the index of the first matrix that did not converge, or -1."""
    T, n = Phi.shape[0], Phi.shape[1]
    d, W, unscale = ws[1], ws[3], ws[9]
    idx = np.empty(n, np.int64)
    for t0 in range(0, T, B):
        bad = _decompose(Phi, t0, ws)
        if bad >= 0:
            return t0 + bad
        for q in range(min(B, T - t0)):
            _descending(d, q, idx)
            for i in range(n):
                s[t0 + q, i] = d[idx[i], q] * unscale[q]
                for l in range(n):
                    V[t0 + q, l, i] = W[idx[i], l, q]
    return -1


@jit
def _mdl_stack(Phi, phi, yvar, n_obs, full, rcond, h, order, ws):
    """For every ``t``: the eigendecomposition of ``Phi[t]``, the order (MDL, or every eigenvalue above
    ``rcond`` times the largest when ``full``) and the solution ``h[t]`` (``ws``: :func:`_workspace`); the
    index of the first matrix whose eigenvalues did not converge, or -1."""
    T, n = Phi.shape[0], Phi.shape[1]
    d, W, unscale = ws[1], ws[3], ws[9]
    idx = np.empty(n, np.int64)
    proj = np.empty(n)
    inv = np.empty(n)
    log_n = np.log(n_obs)
    for t0 in range(0, T, B):
        bad = _decompose(Phi, t0, ws)
        if bad >= 0:
            return t0 + bad
        for q in range(min(B, T - t0)):
            t = t0 + q
            _descending(d, q, idx)
            top = d[idx[0], q] * unscale[q]
            for i in range(n):                    # phi on eigenvector i; 1 / eigenvalue where kept
                acc = 0.0
                for l in range(n):
                    acc += W[idx[i], l, q] * phi[t, l]
                proj[i] = acc
                si = d[idx[i], q] * unscale[q]
                inv[i] = 1.0 / si if si > rcond * top else 0.0
            if full:
                kept = 0
                for i in range(n):
                    kept += inv[i] != 0.0
                order[t] = kept
            else:
                # MDL(k) = (1 + k ln(n_obs) / n_obs) (yvar - explained_k), its first minimum over the kept
                # k (none kept: order 1 with a zero coefficient, as an argmin over infinities gives)
                best = np.inf
                chosen = 1
                explained = 0.0
                for i in range(n):
                    explained += proj[i] ** 2 * inv[i]
                    mdl = (1.0 + (i + 1) * log_n / n_obs) * (yvar[t] - explained)
                    if inv[i] != 0.0 and mdl < best:
                        best = mdl
                        chosen = i + 1
                order[t] = chosen
                for i in range(chosen, n):
                    inv[i] = 0.0
            for l in range(n):
                h[t, l] = 0.0
            for i in range(n):
                c = proj[i] * inv[i]
                for l in range(n):
                    h[t, l] += c * W[idx[i], l, q]
    return -1


@jit
def _lagged_gram(U, L, Phi, C):
    """``Phi[i] = X[i]^T X[i]`` for the lagged input ``X[i, r, j] = U[i + L - 1 - j, r]``:
    ``Phi[i, j, l] = C[|j - l|, i + L - 1 - min(j, l)]`` with ``C[k, s] = sum_r U[s, r] U[s - k, r]``, the
    products of samples k apart, each formed once (the Gram matrices of neighbouring times share all but
    their first row and column)."""
    n, R = U.shape
    for s in range(n):
        for k in range(min(L, s + 1)):            # L sums side by side, each over r in order
            acc = 0.0
            for r in range(R):
                acc += U[s, r] * U[s - k, r]
            C[k, s] = acc
    for i in range(Phi.shape[0]):
        for j in range(L):
            for l in range(j, L):
                Phi[i, j, l] = Phi[i, l, j] = C[l - j, i + L - 1 - j]


def lagged_gram(U: np.ndarray, L: int) -> np.ndarray:
    """The Gram matrices of the lagged input of every realization, as ``gram_stack(lagged(U, M1, M2))`` of
    :mod:`jointbench.estimators._tvirf` (``L = M1 + M2 + 1``), from the products of the samples ``0 ... L - 1``
    apart (``n L R`` products instead of ``(n - L + 1) L^2 R``).

    Parameters
    ----------
    U : ndarray (n, R)
        Input of each realization.
    L : int
        Lags.

    Returns
    -------
    ndarray (n - L + 1, L, L)
        ``Phi[i, j, l] = sum_r U[i + L - 1 - j, r] U[i + L - 1 - l, r]``: row ``i`` belongs to sample
        ``i + M2``, column ``j`` to lag ``j - M1``.
    """
    U = _stack(U)
    n = U.shape[0]
    Phi = np.empty((n - L + 1, L, L))
    _lagged_gram(U, L, Phi, np.empty((L, n)))
    return Phi


def _stack(a: np.ndarray) -> np.ndarray:
    """``a`` as C-ordered float64 (one compiled specialization)."""
    return np.ascontiguousarray(a, dtype=np.float64)


def _failed(t: int) -> None:
    if t >= 0:
        raise np.linalg.LinAlgError(f"Eigenvalues did not converge (matrix {t} of the stack)")


def eigh_descending(Phi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Eigendecomposition of every symmetric matrix of a stack, eigenvalues descending.

    Parameters
    ----------
    Phi : ndarray (T, n, n)
        Symmetric matrices (only their values are used as given: both triangles should agree).

    Returns
    -------
    s : ndarray (T, n)
        Eigenvalues, descending.
    V : ndarray (T, n, n)
        Orthonormal eigenvectors in the columns: ``Phi[t] = V[t] diag(s[t]) V[t]^T``.

    Raises
    ------
    numpy.linalg.LinAlgError
        The QR iteration did not converge (non-finite entries).
    """
    Phi = _stack(Phi)
    T, n = Phi.shape[0], Phi.shape[-1]
    s, V = np.empty((T, n)), np.empty((T, n, n))
    _failed(_eigh_stack(Phi, s, V, _workspace(n)))
    return s, V


def mdl_pinv(Phi: np.ndarray, phi: np.ndarray, yvar: np.ndarray, n_obs: float, full: bool,
             rcond: float) -> tuple[np.ndarray, np.ndarray]:
    """The pseudo-inverse solutions of :func:`jointbench.estimators._tvirf.mdl_solve` (which documents
    them), in one compiled pass over the stack.

    Returns
    -------
    h : ndarray (T, n)
    order : ndarray of int (T,)

    Raises
    ------
    numpy.linalg.LinAlgError
        The QR iteration did not converge (non-finite entries).
    """
    Phi, phi, yvar = _stack(Phi), _stack(phi), _stack(yvar)
    T, n = Phi.shape[0], Phi.shape[-1]
    h, order = np.empty((T, n)), np.empty(T, np.int64)
    _failed(_mdl_stack(Phi, phi, yvar, float(n_obs), bool(full), float(rcond), h, order, _workspace(n)))
    return h, order

