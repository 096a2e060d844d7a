"""The two loops of backend ``ltv`` compiled (numba): the per-step series and the blockwise recursion.

Private module of :mod:`jointbench.sims.backend_ltv`, imported on its first simulation (numba costs a
few tenths of a second to import; compiled by :mod:`jointbench.core.compiled`, cached on disk). Each kernel
does, for every element, the operations of the numpy formulation it replaced, in the same order (IEEE
arithmetic, no fused multiply-add), so the numbers are the same to the last bit (tests/test_sims_tv.py
keeps the numpy formulations as references). In numpy each operation was a pass over arrays of
thousands of steps (about 150 passes for the series, 30 per block step for the recursion); here each
step's values stay in registers (issue 22: the integrator was the largest part of xu1998 and Table II).

References
----------
Moler & Van Loan 2003, SIAM Review 45(1), methods 3 (scaling and squaring) and 8 (Cayley–Hamilton);
Blelloch 1990, "Prefix sums and their applications" (the blockwise scan of an affine recursion).
"""
from __future__ import annotations

import numpy as np

from jointbench.core.compiled import jit

#: steps of the series computed together: the innermost loop runs over them (vector instructions), and
#: their temporaries stay in the first-level cache
LANES = 256


@jit
def series(p, q, tau, m, inv_fact, out):
    """:func:`jointbench.sims.backend_ltv._series` for every step: ``out`` (6, n) receives the
    coefficients ``(c0, c1)`` of E, J1 and J2 of ``A = [[0, 1], [p, q]]`` for the step ``tau 2^m``.

    ``inv_fact[k] = 1 / (k + 2)!`` for ``k = 0 ... terms``: the Taylor sums ``S_2`` by Horner's rule from
    ``inv_fact[terms]`` down, then ``S_1``, ``E`` and ``m`` doublings, each value by the expression (and
    in the order) of the numpy formulation; :data:`LANES` steps at a time, every stage a loop over them.
    """
    n = p.shape[0]
    terms = inv_fact.shape[0] - 1
    W = np.empty((8, LANES))
    a, b, ea, eb, j1a, j1b, j2a, j2b = W[0], W[1], W[2], W[3], W[4], W[5], W[6], W[7]
    t2 = tau * tau
    for s0 in range(0, n, LANES):
        nl = min(LANES, n - s0)
        P, Q = p[s0:s0 + nl], q[s0:s0 + nl]
        for i in range(nl):
            a[i] = inv_fact[terms]
            b[i] = 0.0
        for k in range(terms - 1, -1, -1):
            c = inv_fact[k]
            for i in range(nl):
                tb = b[i]
                b[i] = a[i] * tau + (Q[i] * tau) * tb
                a[i] = (P[i] * tau) * tb + c
        for i in range(nl):
            tp, tq = P[i] * tau, Q[i] * tau
            s1a = tp * b[i] + 1.0
            s1b = a[i] * tau + tq * b[i]
            ea[i] = tp * s1b + 1.0
            eb[i] = s1a * tau + tq * s1b
            j1a[i], j1b[i] = s1a * tau, s1b * tau
            j2a[i], j2b[i] = a[i] * t2, b[i] * t2
        tt = tau
        for _ in range(m):
            for i in range(nl):
                pe, qe = P[i] * eb[i], Q[i] * eb[i]
                n2a = j1a[i] * tt + j2a[i] + ea[i] * j2a[i] + pe * j2b[i]
                n2b = j1b[i] * tt + j2b[i] + ea[i] * j2b[i] + eb[i] * j2a[i] + qe * j2b[i]
                n1a = ea[i] * j1a[i] + j1a[i] + pe * j1b[i]
                n1b = ea[i] * j1b[i] + j1b[i] + eb[i] * j1a[i] + qe * j1b[i]
                nea = ea[i] * ea[i] + pe * eb[i]
                neb = ea[i] * 2.0 * eb[i] + qe * eb[i]
                ea[i], eb[i], j1a[i], j1b[i], j2a[i], j2b[i] = nea, neb, n1a, n1b, n2a, n2b
            tt *= 2.0
        for r in range(6):
            for i in range(nl):
                out[r, s0 + i] = W[2 + r, i]


@jit
def ends(e00, e01, e10, e11, w0, w1, block, P):
    """Pass 1 of :func:`jointbench.sims.backend_ltv.affine_recursion`: every block of ``block`` steps of
    ``x_k+1 = E_k x_k + w_k`` run from a zero state, its product ``P[0:4, b]`` (00, 01, 10, 11) and its
    end state ``P[4:6, b]`` (steps past the end: the identity with no input), so that the rows of ``P``
    are again such a recursion, one step a block."""
    n = w0.shape[0]
    for bk in range(P.shape[1]):
        i = bk * block
        x, y = w0[i], w1[i]
        p00, p01, p10, p11 = e00[i], e01[i], e10[i], e11[i]
        for j in range(1, block):
            k = i + j
            if k < n:
                a00, a01, a10, a11, u0, u1 = e00[k], e01[k], e10[k], e11[k], w0[k], w1[k]
            else:
                a00, a01, a10, a11, u0, u1 = 1.0, 0.0, 0.0, 1.0, 0.0, 0.0
            x, y = a00 * x + a01 * y + u0, a10 * x + a11 * y + u1
            p00, p01, p10, p11 = (a00 * p00 + a01 * p10, a00 * p01 + a01 * p11,
                                  a10 * p00 + a11 * p10, a10 * p01 + a11 * p11)
        P[0, bk], P[1, bk], P[2, bk], P[3, bk], P[4, bk], P[5, bk] = p00, p01, p10, p11, x, y


@jit
def from_starts(e00, e01, e10, e11, w0, w1, block, sx, sy, ox, oy):
    """Pass 2 of :func:`jointbench.sims.backend_ltv.affine_recursion`: every block of ``block`` steps run
    from its start state ``(sx, sy)[b]`` by the plain recursion, the states into ``ox``, ``oy`` (the
    first one ``(sx, sy)[0]``, the start of the first block)."""
    n = w0.shape[0]
    ox[0], oy[0] = sx[0], sy[0]
    for bk in range(-(-n // block)):
        x, y = sx[bk], sy[bk]
        for k in range(bk * block, min(bk * block + block, n)):
            x, y = e00[k] * x + e01[k] * y + w0[k], e10[k] * x + e11[k] * y + w1[k]
            ox[k + 1], oy[k + 1] = x, y
