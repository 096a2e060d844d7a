"""Backend ``ltv``: exponential-midpoint integration of a time-varying joint held by any apparatus.

The limb ``I theta'' + B(t) theta' + K(t) theta = T_a + T_v`` with the coupling of
:class:`sims.apparatus.Coupling`, ``T_a = g d + g_d d' - k_a theta - b_a theta'``, is a 2-state linear
time-varying system. Over each step [t_k, t_k+1] its coefficients are frozen at the midpoint and the
step is taken exactly for inputs that vary linearly over the step (first-order hold of
``g d + g_d d' + T_v``, with d' from fourth-order central differences, :func:`derivative`). This is the exponential
midpoint rule: second-order accurate in the time variation, exact for constant coefficients (it then agrees with
backend ``lti``), and stable for stiff contacts (e.g. the wrist's 3 kHz pole at 2.5 kHz sampling).

The per-step matrices E = e^{A h}, J1 = ∫_0^h e^{A s} ds, J2 = ∫_0^h J1(s) ds are power series in A, and
by Cayley–Hamilton (A² = q A + p I for A = [[0, 1], [p, q]]) each is ``c0 I + c1 A``: two coefficient
arrays instead of four matrix entries, and a product of two such matrices costs five multiplications
(:func:`step_coefficients`). They are computed for all steps (Taylor series at h / 2^m, then m
doublings: E(2h) = E², J1(2h) = J1 + E J1, J2(2h) = J2 + h J1 + E J2). The recursion
``x_k+1 = E_k x_k + v_k`` is solved blockwise (:func:`affine_recursion`): each block of 32 steps runs
from a zero state and from its true start state, and the block ends, themselves such a recursion 32
times shorter, are solved the same way: each block step one vectorised numpy pass over all blocks.
"""
from __future__ import annotations

import collections
import math
import pickle

import numpy as np

from jointbench.sims.registries import BACKENDS
from jointbench.sims.apparatus import derivative  # noqa: F401 - re-exported: the drive's derivative, shared with lti
from jointbench.sims.backend import Backend, Response

_TAYLOR_TERMS = 12  # at |A tau| <= 0.25 the next term is below 1e-16
#: 1 / (k + 2)! for k = 0 ... _TAYLOR_TERMS, the coefficients of the Taylor sum S_2
_INV_FACT = np.array([1.0 / math.factorial(k + 2) for k in range(_TAYLOR_TERMS + 1)])
_INV_FACT.flags.writeable = False
BLOCK = 32          # steps per block of affine_recursion (16 ... 64 were about equally fast at 1e5 steps)


def step_coefficients(p: np.ndarray, q: np.ndarray, h: float):
    """E, J1, J2 for ``A = [[0, 1], [p, q]]`` (stacks over steps) and step ``h``, as ``c0 I + c1 A``.

    Every matrix here is a power series in ``A``; with ``A² = q A + p I`` (Cayley–Hamilton) it is
    ``c0 I + c1 A``, and ``(a I + b A)(c I + d A) = (a c + p b d) I + (a d + b c + q b d) A``.
    The Taylor sums ``S_j = sum_k X^k / (k + j)!`` of ``X = A tau`` (``tau = h / 2^m``, ``|X| <= 1/4``)
    are evaluated by Horner's rule (``X (a I + b A) = tau (p b I + (a + q b) A)``), then ``m`` doublings.

    Steps with the same ``(p, q)`` as the step before (a square wave or steps hold the coefficients for
    many steps) share one computation when runs are long (bit for bit the same numbers either way).

    Returns
    -------
    E, J1, J2 : tuple of 2 ndarrays each
        Coefficients ``(c0, c1)`` of e^{A h}, ∫_0^h e^{A s} ds and ∫_0^h ∫_0^s e^{A r} dr ds.

    References
    ----------
    Moler & Van Loan 2003, SIAM Review 45(1), methods 3 (scaling and squaring) and 8 (Cayley–Hamilton).
    """
    p, q = np.asarray(p, float), np.asarray(q, float)
    if p.size > 16:
        starts = np.flatnonzero(np.concatenate([[True], (p[1:] != p[:-1]) | (q[1:] != q[:-1])]))
        if len(starts) <= p.size // 16:
            lengths = np.diff(np.append(starts, p.size))
            return tuple(tuple(np.repeat(c, lengths) for c in M) for M in step_coefficients(p[starts], q[starts], h))
    norm = float(np.max(np.abs(p) + np.abs(q) + 1.0)) * h if p.size else 0.0
    m = max(0, int(np.ceil(np.log2(norm / 0.25)))) if norm > 0.25 else 0
    return _series(p, q, h, m)


def _series(p: np.ndarray, q: np.ndarray, h: float, m: int):
    """:func:`step_coefficients` for a stack, with the number ``m`` of doublings given: the Taylor sums at
    ``tau = h / 2^m`` by Horner's rule, then ``m`` doublings, each a few numpy passes over the steps."""
    tau = h / 2.0 ** m
    tp, tq = p * tau, q * tau
    a, b = np.full_like(tp, _INV_FACT[-1]), np.zeros_like(tp)
    for c in _INV_FACT[-2::-1]:                   # S_2 = a I + b A
        a, b = tp * b + c, tau * a + tq * b
    s1a, s1b = tp * b + 1.0, tau * a + tq * b     # S_1 = I + X S_2
    E, J1, J2 = (tp * s1b + 1.0, tau * s1a + tq * s1b), (s1a * tau, s1b * tau), (a * (tau * tau), b * (tau * tau))
    for _ in range(m):                            # E(2t) = E^2, J1(2t) = J1 + E J1, J2(2t) = J2 + t J1 + E J2
        (ea, eb), (j1a, j1b), (j2a, j2b) = E, J1, J2
        pe, qe = p * eb, q * eb
        J2 = (j2a + tau * j1a + ea * j2a + pe * j2b, j2b + tau * j1b + ea * j2b + eb * j2a + qe * j2b)
        J1 = (j1a + ea * j1a + pe * j1b, j1b + ea * j1b + eb * j1a + qe * j1b)
        E = (ea * ea + pe * eb, 2.0 * ea * eb + qe * eb)
        tau *= 2.0
    return E, J1, J2


def step_matrices(p: np.ndarray, q: np.ndarray, h: float):
    """E, J1, J2 of :func:`step_coefficients` written out as components (00, 01, 10, 11) of 2x2 matrices."""
    return tuple((a, b, b * p, a + b * q) for a, b in step_coefficients(p, q, h))


def affine_recursion(E, v0: np.ndarray, v1: np.ndarray, x0: tuple[float, float],
                     block: int = BLOCK) -> tuple[np.ndarray, np.ndarray]:
    """States of ``x_k+1 = E_k x_k + v_k`` (k = 0 ... n-2) from ``x_0``, blockwise.

    ``E`` holds 4 component arrays (00, 01, 10, 11) of length n-1, ``v0``, ``v1`` the two components of
    v_k. The steps are cut into blocks of ``block``; every block is run step by step from a zero state
    (all blocks side by side, one numpy pass per step of a block), which gives its end state as an affine
    map of its start state; the start states then follow from the same recursion over the block ends
    (recursively, until at most ``block`` steps remain, which a plain loop does); a second pass runs every
    block from its true start state. Each state is thus computed by the plain recursion from a nearby exact
    start: the rounding differs from a sequential loop by a few ulp.
    Returns the two state components, length n.

    References
    ----------
    Blelloch 1990, "Prefix sums and their applications" (the blockwise scan of an affine recursion).
    """
    n1 = len(v0)
    if n1 <= block:
        e00, e01, e10, e11 = (np.asarray(c, float).tolist() for c in E)
        w0, w1 = np.asarray(v0, float).tolist(), np.asarray(v1, float).tolist()
        x, y = float(x0[0]), float(x0[1])
        xs, ys = [x], [y]
        for k in range(n1):
            x, y = e00[k] * x + e01[k] * y + w0[k], e10[k] * x + e11[k] * y + w1[k]
            xs.append(x)
            ys.append(y)
        return np.array(xs), np.array(ys)
    nb = -(-n1 // block)

    def blocks(c, fill):                          # (block, nb): step j of every block in row j
        return np.concatenate([np.asarray(c, float), np.full(nb * block - n1, fill)]).reshape(nb, block).T

    e00, e01, e10, e11 = (blocks(c, f) for c, f in zip(E, (1.0, 0.0, 0.0, 1.0)))
    w0, w1 = blocks(v0, 0.0), blocks(v1, 0.0)
    x, y = w0[0].copy(), w1[0].copy()             # every block from a zero state: its end and its product
    P00, P01, P10, P11 = e00[0].copy(), e01[0].copy(), e10[0].copy(), e11[0].copy()
    for j in range(1, block):
        a00, a01, a10, a11 = e00[j], e01[j], e10[j], e11[j]
        x, y = a00 * x + a01 * y + w0[j], a10 * x + a11 * y + w1[j]
        P00, P01, P10, P11 = (a00 * P00 + a01 * P10, a00 * P01 + a01 * P11,
                              a10 * P00 + a11 * P10, a10 * P01 + a11 * P11)
    sx, sy = affine_recursion((P00, P01, P10, P11), x, y, x0, block)    # the start of every block
    X, Y = np.empty((block, nb)), np.empty((block, nb))
    x, y = sx[:-1], sy[:-1]
    for j in range(block):                        # every block from its start
        x, y = e00[j] * x + e01[j] * y + w0[j], e10[j] * x + e11[j] * y + w1[j]
        X[j], Y[j] = x, y
    return np.concatenate([[x0[0]], X.T.ravel()[:n1]]), np.concatenate([[x0[1]], Y.T.ravel()[:n1]])


_WEIGHTS: collections.OrderedDict = collections.OrderedDict()
WEIGHTS_MAX_BYTES = 256e6
WEIGHTS_MAX_KEY = 1 << 16
_WEIGHTS_STATS = {"computed": 0, "reused": 0}


def _weights_key(joint, coupling, n: int, h: float) -> bytes | None:
    """The memo key of :func:`step_weights`, or None for a joint given by arrays or by a description longer
    than :data:`WEIGHTS_MAX_KEY` (an estimated model's or a recorded time course: one of a kind)."""
    try:
        if any(isinstance(v, np.ndarray) for v in (*vars(joint).values(), *vars(coupling).values())):
            return None
        key = pickle.dumps((joint, coupling, int(n), float(h)), protocol=4)
    except (TypeError, AttributeError, pickle.PicklingError):
        return None
    return key if len(key) <= WEIGHTS_MAX_KEY else None


def step_weights(joint, coupling, n: int, h: float):
    """The per-step pieces of the exponential midpoint rule for ``n`` samples at step ``h`` (shared with the
    time-stepping path, :mod:`sims.backend_stepping`): the sample times ``t``, the inertia at the steps'
    midpoints ``Im``, ``p``, ``q`` of ``A = [[0, 1], [p, q]]``, the transition ``E`` (4 components) and
    column 1 of J1 and J2 ``(J1_01, J1_11, J2_01, J2_11)`` (``(c0 I + c1 A)[:, 1] = (c1, c0 + q c1)``).

    They depend on the joint's time course and the coupling only, not on the input: kept for the last
    joints of this process (:data:`WEIGHTS_MAX_BYTES`), as read-only arrays."""
    key = _weights_key(joint, coupling, n, h)
    if key is not None and key in _WEIGHTS:
        _WEIGHTS.move_to_end(key)
        _WEIGHTS_STATS["reused"] += 1
        return _WEIGHTS[key][0]
    out = _step_weights(joint, coupling, n, h)
    _WEIGHTS_STATS["computed"] += 1
    if key is not None:
        arrays = [out[0], out[1], out[2], out[3], *out[4], *out[5]]
        for a in arrays:
            a.setflags(write=False)
        _WEIGHTS[key] = (out, sum(a.nbytes for a in arrays))
        while sum(m for _, m in _WEIGHTS.values()) > WEIGHTS_MAX_BYTES and len(_WEIGHTS) > 1:
            _WEIGHTS.popitem(last=False)
    return out


def _step_weights(joint, coupling, n: int, h: float):
    """:func:`step_weights` computed."""
    t = np.arange(n) * h
    Im, Bm, Km = joint.coefficients_at(t[:-1] + h / 2)
    p = -(Km + coupling.k_a) / Im
    q = -(Bm + coupling.b_a) / Im
    (ea, eb), (j1a, j1b), (j2a, j2b) = step_coefficients(p, q, h)
    E = (ea, eb, p * eb, ea + q * eb)
    return t, Im, p, q, E, (j1b, j1a + q * j1b, j2b, j2a + q * j2b)


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
        t, Im, p, q, E, (J1_01, J1_11, J2_01, J2_11) = step_weights(joint, c, n, h)
        w, d_dot = c.drive_input(d, fs)
        w = w + tv                           # the whole input, held linearly over each step
        inv_i = 1.0 / Im
        # v_k = (J1 - J2/h) b w_k + (J2/h) b w_k+1, with b = [0, 1/I]: only column 1 of J1, J2 matters
        c0 = (J1_01 - J2_01 / h) * w[:-1] + J2_01 / h * w[1:]
        c1 = (J1_11 - J2_11 / h) * w[:-1] + J2_11 / h * w[1:]
        theta, vel = affine_recursion(E, c0 * inv_i, c1 * inv_i, (float(x0[0]), float(x0[1])))
        I, B, K = joint.coefficients_at(t)
        t_a = c.torque(d, d_dot, theta, vel)
        acc = (t_a + tv - B * vel - K * theta) / I
        return Response(angle=theta, velocity=vel, acceleration=acc, torque_measured=t_a,
                        torque_impedance=I * acc + B * vel + K * theta)
