"""Backend ``ltv``: exponential-midpoint integration of a time-varying joint held by any apparatus.

The limb ``I theta'' + B(t) theta' + K(t) theta = T_a + T_v`` with the coupling of
:class:`sims.apparatus.Coupling`, ``T_a = g d + g_d d' - k_a theta - b_a theta'``, is a 2-state linear
time-varying system. Over each step [t_k, t_k+1] its coefficients are frozen at the midpoint and the
step is taken exactly for inputs that vary linearly over the step (first-order hold of
``g d + g_d d' + T_v``, with d' from fourth-order central differences, :func:`derivative`). This is the exponential midpoint
rule: second-order accurate in the time variation, exact for constant coefficients (it then agrees with
backend ``lti``), and stable for stiff contacts (e.g. the wrist's 3 kHz pole at 2.5 kHz sampling).

The per-step matrices E = e^{A h}, J1 = ∫_0^h e^{A s} ds, J2 = ∫_0^h J1(s) ds are computed for all steps
at once (Taylor series at h / 2^m, then m doublings: E(2h) = E², J1(2h) = J1 + E J1,
J2(2h) = J2 + h J1 + E J2), and the recursion ``x_k+1 = E_k x_k + v_k`` is solved by a parallel prefix
scan over affine maps (log2 n vectorised passes), so there is no Python loop over samples.
"""
from __future__ import annotations

import math

import numpy as np

from sims import BACKENDS
from sims.apparatus import derivative  # noqa: F401 - re-exported: the drive's derivative, shared with lti
from sims.backend import Backend, Response

_TAYLOR_TERMS = 12  # at |A tau| <= 0.25 the next term is below 1e-16


def _mul(a, b):
    """Products of stacks of 2x2 matrices given as 4-tuples (a00, a01, a10, a11) of arrays."""
    a00, a01, a10, a11 = a
    b00, b01, b10, b11 = b
    return (a00 * b00 + a01 * b10, a00 * b01 + a01 * b11, a10 * b00 + a11 * b10, a10 * b01 + a11 * b11)


def _add(a, b):
    return tuple(x + y for x, y in zip(a, b))


def step_matrices(p: np.ndarray, q: np.ndarray, h: float):
    """E, J1, J2 for ``A = [[0, 1], [p, q]]`` (stacks over steps) and step ``h``.

    Returns
    -------
    E, J1, J2 : tuple of 4 ndarrays each
        Components (00, 01, 10, 11) of e^{A h}, ∫_0^h e^{A s} ds and ∫_0^h ∫_0^s e^{A r} dr ds.
    """
    norm = float(np.max(np.abs(p) + np.abs(q) + 1.0)) * h
    m = max(0, int(np.ceil(np.log2(norm / 0.25)))) if norm > 0.25 else 0
    tau = h / 2.0 ** m
    zero, one = np.zeros_like(p), np.ones_like(p)
    A = (zero, one * tau, p * tau, q * tau)
    ident = (one, zero, zero, one)
    # S_j = sum_{k=0}^{T} X^k / (k + j)! for X = A tau: Horner for S_2, then S_1 = I + X S_2, S_0 = I + X S_1
    S2 = tuple(c / math.factorial(_TAYLOR_TERMS + 2) for c in ident)
    for k in range(_TAYLOR_TERMS - 1, -1, -1):
        S2 = _add(_mul(A, S2), tuple(c / math.factorial(k + 2) for c in ident))
    S1 = _add(ident, _mul(A, S2))
    E = _add(ident, _mul(A, S1))
    J1 = tuple(c * tau for c in S1)
    J2 = tuple(c * tau * tau for c in S2)
    for _ in range(m):
        J2 = _add(_add(J2, tuple(c * tau for c in J1)), _mul(E, J2))
        J1 = _add(J1, _mul(E, J1))
        E = _mul(E, E)
        tau *= 2.0
    return E, J1, J2


def affine_scan(E, v0: np.ndarray, v1: np.ndarray, x0: tuple[float, float]) -> tuple[np.ndarray, np.ndarray]:
    """States of ``x_k+1 = E_k x_k + v_k`` (k = 0 ... n-2) from ``x_0``, by a parallel prefix scan.

    ``E`` holds 4 component arrays of length n-1, ``v0``, ``v1`` the two components of v_k.
    Returns the two state components, length n.
    """
    P = [c.copy() for c in E]
    q0, q1 = v0.copy(), v1.copy()
    n1 = len(q0)
    s = 1
    while s < n1:
        a = [c[s:] for c in P]
        b = [c[:-s] for c in P]
        nq0 = a[0] * q0[:-s] + a[1] * q1[:-s] + q0[s:]
        nq1 = a[2] * q0[:-s] + a[3] * q1[:-s] + q1[s:]
        nP = _mul(a, b)
        for c, new in zip(P, nP):
            c[s:] = new
        q0[s:], q1[s:] = nq0, nq1
        s *= 2
    x = np.empty(n1 + 1)
    y = np.empty(n1 + 1)
    x[0], y[0] = x0
    x[1:] = P[0] * x0[0] + P[1] * x0[1] + q0
    y[1:] = P[2] * x0[0] + P[3] * x0[1] + q1
    return x, y


@BACKENDS.register("ltv")
class LTVBackend(Backend):
    """Time-varying joint + apparatus, exponential midpoint rule with a first-order hold of the inputs.

    References
    ----------
    Xu & Hollerbach 1998, eq. 7 (time-varying elbow); van de Ruit et al. 2018, eqs. 11-13 (wrist with
    contact); Hochbruck & Ostermann 2010, Acta Numerica 19, Sec. 3 (exponential integrators).
    """

    name = "ltv"

    def run(self, joint, apparatus, drive: np.ndarray, voluntary: np.ndarray, fs: float,
            x0: tuple[float, float] = (0.0, 0.0)) -> Response:
        """Simulate at ``fs`` Hz from state ``x0`` = (theta, theta') at the first sample.

        Parameters
        ----------
        joint : object with ``coefficients_at(t)``
            Limb model (time-varying or not).
        apparatus : object with ``coupling(joint)``
            How the drive acts on the limb.
        drive, voluntary : ndarray
            Drive signal d (rad or N·m) and voluntary torque T_v (N·m), one sample per step.
        fs : float
            Simulation rate (Hz).

        Returns
        -------
        Response
            theta, theta', theta'' at the samples, the measured torque T_a and the impedance torque
            ``I theta'' + B theta' + K theta`` (with B, K at the sample instants).
        """
        d = np.asarray(drive, float)
        tv = np.asarray(voluntary, float)
        if d.shape != tv.shape or d.ndim != 1 or len(d) < 2:
            raise ValueError(f"drive and voluntary torque must be 1-D of equal length >= 2, got {d.shape}, {tv.shape}")
        c = apparatus.coupling(joint)
        h = 1.0 / fs
        n = len(d)
        t = np.arange(n) * h
        Im, Bm, Km = joint.coefficients_at(t[:-1] + h / 2)
        p = -(Km + c.k_a) / Im
        q = -(Bm + c.b_a) / Im
        E, J1, J2 = step_matrices(p, q, h)
        w, d_dot = c.drive_input(d, fs)
        w = w + tv                           # the whole input, held linearly over each step
        inv_i = 1.0 / Im
        # v_k = (J1 - J2/h) b w_k + (J2/h) b w_k+1, with b = [0, 1/I]: only column 1 of J1, J2 matters
        c0 = (J1[1] - J2[1] / h) * w[:-1] + J2[1] / h * w[1:]
        c1 = (J1[3] - J2[3] / h) * w[:-1] + J2[3] / h * w[1:]
        theta, vel = affine_scan(E, c0 * inv_i, c1 * inv_i, (float(x0[0]), float(x0[1])))
        I, B, K = joint.coefficients_at(t)
        t_a = c.torque(d, d_dot, theta, vel)
        acc = (t_a + tv - B * vel - K * theta) / I
        return Response(angle=theta, velocity=vel, acceleration=acc, torque_measured=t_a,
                        torque_impedance=I * acc + B * vel + K * theta)
