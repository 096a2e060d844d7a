"""The recursion and the per-sample solve of FSEWLS's EWLS (eq. 6), compiled (numba).

Private module of :func:`jointbench.estimators._fsewls_kernels.ewls`, imported on its first fit (compiled
by :mod:`jointbench.core.compiled`, cached on disk). Each loop does, for every sample, the operations of the
numpy formulation it replaced in the same order (IEEE arithmetic, no fused multiply-add), so the
estimates are the same to the last bit (tests/test_fsewls.py keeps that formulation as the reference):
the products of the regressors at the samples and the mid-points, the RK4 drive ``w0 f0 + wm fm + w1 f1``,
the recursion ``x_k = c x_k-1 + drive_k`` that
``scipy.signal.lfilter([1], [1, -c])`` ran, and the column-scaled ``L D L^T`` solve of the 3 x 3 information
matrix. In numpy they were some forty passes over the nine rows of the record (issue 22: FSEWLS was the
largest part of xu1998 after the simulation).

References
----------
Xu, Y. & Hollerbach, J. M. (1998). IEEE Trans. Biomed. Eng. 45(9), eqs. 5-6 and Sec. II-D.
"""
from __future__ import annotations

import numpy as np

from jointbench.core.compiled import jit


@jit
def recursion(P, y, w0, wm, w1, c, start, out):
    """``out[:, 0] = start`` and ``out[:, k] = c out[:, k-1] + (w0 f_k-1 + wm fm_k + w1 f_k)`` for the nine
    rows ``f = [unique entries of Phi Phi^T, Phi y]`` summed over the records (``P`` (3, R, n): the
    regressors, ``y`` (R, n)), ``f`` at the samples and ``fm`` at the mid-points, where ``Phi`` and ``y`` are
    ``0.5 (a_k + a_k-1)``; sums over the records in their order from 0, as ``numpy.einsum`` adds them."""
    R, n = y.shape
    f0 = np.empty(9)
    f1 = np.empty(9)
    fm = np.empty(9)
    x = np.empty(9)
    _products(P, y, 0, 0.0, f0)
    for m in range(9):
        x[m] = 0.0 + start[m]                     # lfilter from rest: 0 + the first input
        out[m, 0] = x[m]
    for k in range(1, n):
        _products(P, y, k, 0.0, f1)
        _products(P, y, k, 0.5, fm)
        for m in range(9):
            d = f0[m] * w0 + fm[m] * wm + f1[m] * w1
            x[m] = c * x[m] + d
            out[m, k] = x[m]
            f0[m] = f1[m]


@jit
def _products(P, y, k, mid, f):
    """The nine products of sample ``k`` (``mid == 0``) or of the mid-point before it (``mid == 0.5``:
    ``(a_k + a_k-1) 0.5``), summed over the records, into ``f``."""
    for m in range(9):
        f[m] = 0.0
    for r in range(y.shape[0]):
        if mid == 0.0:
            p0, p1, p2, yk = P[0, r, k], P[1, r, k], P[2, r, k], y[r, k]
        else:
            p0, p1, p2 = (P[0, r, k] + P[0, r, k - 1]) * mid, (P[1, r, k] + P[1, r, k - 1]) * mid, \
                (P[2, r, k] + P[2, r, k - 1]) * mid
            yk = (y[r, k] + y[r, k - 1]) * mid
        f[0] += p0 * p0
        f[1] += p0 * p1
        f[2] += p0 * p2
        f[3] += p1 * p1
        f[4] += p1 * p2
        f[5] += p2 * p2
        f[6] += p0 * yk
        f[7] += p1 * yk
        f[8] += p2 * yk


@jit
def solve3(x, s, out):
    """``R^-1 r`` per sample into ``out`` (n, 3) from ``x`` (9, n) = [the unique entries of the symmetric
    ``R``, ``r``], the columns scaled by ``s`` (3,), ``R = L D L^T`` written out; False when a pivot is not
    positive (``R`` not positive definite at some sample), True otherwise."""
    n = x.shape[1]
    s00, s01, s02, s11, s12, s22 = s[0] * s[0], s[0] * s[1], s[0] * s[2], s[1] * s[1], s[1] * s[2], s[2] * s[2]
    ok = True
    for k in range(n):
        a00, a01, a02 = x[0, k] * s00, x[1, k] * s01, x[2, k] * s02
        a11, a12, a22 = x[3, k] * s11, x[4, k] * s12, x[5, k] * s22
        b0, b1, b2 = x[6, k] * s[0], x[7, k] * s[1], x[8, k] * s[2]
        l10 = a01 / a00
        l20 = a02 / a00
        d1 = a11 - l10 * a01
        e12 = a12 - l20 * a01
        l21 = e12 / d1
        d2 = a22 - l20 * a02 - l21 * e12
        if not (d1 > 0 and d2 > 0 and a00 > 0):
            ok = False
        z1 = b1 - l10 * b0
        x2 = (b2 - l20 * b0 - l21 * z1) / d2
        x1 = (z1 - e12 * x2) / d1
        x0 = (b0 - a01 * x1 - a02 * x2) / a00
        out[k, 0], out[k, 1], out[k, 2] = x0 * s[0], x1 * s[1], x2 * s[2]
    return ok

