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
times shorter, are solved the same way. Both loops are compiled (:mod:`jointbench.sims._ltv_kernels`,
numba; issue 22), with the operations of their numpy formulation in the same order, so the numbers are
those of that formulation to the last bit (tests/test_sims_tv.py keeps it as the reference). They pay for
themselves (issue 34 weighed them against the numpy passes: results/benchmarks.md).
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
    """:func:`step_coefficients` for a stack, with the number ``m`` of doublings given: the compiled loop
    :func:`jointbench.sims._ltv_kernels.series` (the expressions of tests/test_sims_tv.py's
    ``_series_plain``, bit for bit)."""
    from jointbench.sims import _ltv_kernels

    p, q = _same_type([np.ascontiguousarray(p, dtype=float), np.ascontiguousarray(q, dtype=float)])
    out = np.empty((6, p.size))
    _ltv_kernels.series(p, q, h / 2.0 ** m, m, _INV_FACT, out)
    return (out[0], out[1]), (out[2], out[3]), (out[4], out[5])


def step_matrices(p: np.ndarray, q: np.ndarray, h: float):
    """E, J1, J2 of :func:`step_coefficients` written out as components (00, 01, 10, 11) of 2x2 matrices."""
    return tuple((a, b, b * p, a + b * q) for a, b in step_coefficients(p, q, h))


def affine_recursion(E, v0: np.ndarray, v1: np.ndarray, x0: tuple[float, float]) -> tuple[np.ndarray, np.ndarray]:
    """States of ``x_k+1 = E_k x_k + v_k`` (k = 0 ... n-2) from ``x_0``, blockwise.

    ``E`` holds 4 component arrays (00, 01, 10, 11) of length n-1, ``v0``, ``v1`` the two components of
    v_k. The steps are cut into blocks of :data:`BLOCK`; every block is run step by step from a zero state,
    which gives its end state as an affine map of its start state; the start states then follow from the
    same recursion over the block ends (recursively, until at most BLOCK steps remain, which a plain
    loop does); a second pass runs every block from its true start state. Each state is thus computed by
    the plain recursion from a nearby exact start: the rounding differs from a sequential loop by a few
    ulp. (The block structure made the recursion a few vectorised numpy passes per block step; compiled
    now, :func:`jointbench.sims._ltv_kernels.ends` and :func:`~jointbench.sims._ltv_kernels.from_starts` for each
    level, it keeps the same operations, so the same numbers.)
    Returns the two state components, length n.
    """
    from jointbench.sims import _ltv_kernels as kernels

    level = _same_type([np.ascontiguousarray(c, dtype=float) for c in (*E, v0, v1)])
    levels = [level]                          # the steps, then the blocks as steps, ... until one block is left
    while len(levels[-1][4]) > BLOCK:
        P = np.empty((6, -(-len(levels[-1][4]) // BLOCK)))
        kernels.ends(*levels[-1], BLOCK, P)
        levels.append(_same_type(list(P)))
    sx, sy = np.array([float(x0[0])]), np.array([float(x0[1])])
    for level in reversed(levels):            # the states of each level, from the starts of its blocks
        ox, oy = np.empty(len(level[4]) + 1), np.empty(len(level[4]) + 1)
        kernels.from_starts(*level, BLOCK, *_same_type([sx, sy]), ox, oy)
        sx, sy = ox, oy
    return sx, sy


def _same_type(arrays: list[np.ndarray]) -> list[np.ndarray]:
    """The arrays as read-only views: numba compiles one specialization per signature, and a read-only
    array (the memo of :func:`step_weights`) is typed apart from a writable one."""
    out = []
    for a in arrays:
        if a.flags.writeable:
            a = a.view()
            a.flags.writeable = False
        out.append(a)
    return out


#: the step weights of the last joints simulated in this process, by pickled (joint, coupling, n, h): trials of
#: one joint time course with other perturbations (another seed) share them; arrays read-only, so a hit is
#: the same numbers and no caller can change them
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
