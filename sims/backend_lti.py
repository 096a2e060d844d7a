"""Backend ``lti``: exact first-order-hold discretization of the linear time-invariant closed loop.

The limb ``I theta'' + B theta' + K theta = T_a + T_v`` and the apparatus' linear coupling
``T_a = g d + g_d d' - k_a theta - b_a theta'`` (:class:`sims.apparatus.Coupling`; position servo:
g = k_a = K_a, g_d = b_a = B_a, d = theta_r; torque drive: g = 1, d = T_p) form a 2-state continuous
system driven by ``w = g d + g_d d' + T_v``. It is discretized exactly for an input that varies
linearly between samples (first-order hold, matrix exponential of the augmented matrix), and run as
second-order recursive filters (theta and theta' from w) with :func:`scipy.signal.lfilter`: no Python
loop over samples. The drive's derivative (a servo damping) comes from the same fourth-order
differences as in backend ``ltv``, so the two backends agree on every apparatus.

Why first-order hold: the command and the voluntary torque are continuous signals. Holding them
constant over each sample (zero-order hold) makes theta'' jump at every sample, and the torque read at
the sample instant, K_a (theta_r - theta), is then half a sample ahead of the smooth sampled angle: an
estimator sees a spurious damping of K_a dt / 2 (3 N·m·s/rad for K_a = 30 000 at 5 kHz, more than
twice the elbow's B). With a linear hold theta'' is continuous and the sampled torque is exactly
I theta'' + B theta' + K theta - T_v at the sample instants.
"""
from __future__ import annotations

import numpy as np
from jointbench.core.lazy import scipy_linalg, scipy_signal as sps   # imported on first use (0.8 CPU-s)

from jointbench.core.errors import ConfigError, Incompatible
from jointbench.sims.registries import BACKENDS
from jointbench.sims.backend import Backend, Response, lti_applies


def closed_loop(joint, apparatus) -> tuple[np.ndarray, np.ndarray]:
    """Continuous closed-loop matrices of limb and apparatus.

    Parameters
    ----------
    joint : object with ``state_space()``
        Time-invariant joint model (admittance, net torque -> [theta, theta']).
    apparatus : object with ``coupling(joint)``
        Its coupling gives the restoring stiffness k_a and damping b_a on the limb.

    Returns
    -------
    A : ndarray, shape (2, 2)
        State matrix for x = [theta, theta'].
    B : ndarray, shape (2, 1)
        Input matrix for the input ``w = g d + g_d d' + T_v``.

    References
    ----------
    Westwick & Perreault 2012, Fig. 1 and eqs. 3-8.
    """
    if not getattr(joint, "time_invariant", False) or not hasattr(joint, "state_space"):
        raise ConfigError(f"backend 'lti' needs a time-invariant joint model with a state space; "
                          f"got {type(joint).__name__}")
    a, b, _, _ = joint.state_space()
    a = np.asarray(a, float)
    b = np.asarray(b, float).reshape(2, 1)
    c = apparatus.coupling(joint)
    A = a - b @ np.array([[c.k_a, c.b_a]])
    return A, b


def foh(A: np.ndarray, B: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Exact first-order-hold discretization ``x[k+1] = Ad x[k] + G0 u[k] + G1 u[k+1]``.

    ``expm([[A dt, B dt, 0], [0, 0, I], [0, 0, 0]]) = [[Ad, P, Q], ...]`` with ``G1 = Q`` and
    ``G0 = P - Q`` (Franklin, Powell & Workman, Digital Control of Dynamic Systems, Sec. 6.3.2).
    """
    n, m = B.shape
    M = np.zeros((n + 2 * m, n + 2 * m))
    M[:n, :n] = A * dt
    M[:n, n:n + m] = B * dt
    M[n:n + m, n + m:] = np.eye(m)
    E = scipy_linalg.expm(M)
    P, Q = E[:n, n:n + m], E[:n, n + m:]
    return E[:n, :n], P - Q, Q


def transfer_coefficients(Ad: np.ndarray, G0: np.ndarray, G1: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Numerators ``num[i, j]`` (state i from input j) and the common denominator, in powers of z⁻¹.

    ``X(z) = adj(zI - Ad) (z G1 + G0) U(z) / det(zI - Ad)`` with adj(zI - Ad) = [[z - a11, a01],
    [a10, z - a00]] and det = z² - tr(Ad) z + det(Ad).
    """
    (a00, a01), (a10, a11) = Ad
    den = np.array([1.0, -(a00 + a11), a00 * a11 - a01 * a10])
    num = np.zeros((2, G0.shape[1], 3))
    for j in range(G0.shape[1]):
        g0, g1 = G1[:, j]
        h0, h1 = G0[:, j]
        num[0, j] = (g0, h0 - a11 * g0 + a01 * g1, -a11 * h0 + a01 * h1)
        num[1, j] = (g1, a10 * g0 + h1 - a00 * g1, a10 * h0 - a00 * h1)
    return num, den


@BACKENDS.register("lti")
class LTIBackend(Backend):
    """Exact FOH simulation of a time-invariant joint held by an apparatus (Fig. 1 of the paper).

    The inputs (drive and voluntary torque) vary linearly between samples, so the states at the
    sample instants are exact for that input; the system is at rest before the first sample (the
    inputs ramp from zero over the sample before t = 0).

    References
    ----------
    Westwick & Perreault 2012, Fig. 1 and eqs. 3-8 (Sec. II-A); Sec. IV (apparatus).
    """

    name = "lti"

    def check(self, experiment) -> None:
        super().check(experiment)
        reason = lti_applies(experiment)
        if reason:
            raise Incompatible(f"backend 'lti' cannot simulate this experiment: {reason}; use 'ltv' or 'analytic'")

    def run(self, joint, apparatus, drive: np.ndarray, voluntary: np.ndarray, fs: float) -> Response:
        """Simulate at ``fs`` Hz.

        Parameters
        ----------
        joint : SecondOrderJoint or another time-invariant joint
            Limb model.
        apparatus : object with ``coupling(joint)``
            How ``drive`` acts on the limb.
        drive : ndarray
            Position command theta_r (rad) or applied torque T_p (N·m), one sample per step.
        voluntary : ndarray
            Voluntary torque T_v (N·m), same length.
        fs : float
            Simulation rate (Hz).

        Returns
        -------
        Response
            theta, theta', theta'' (from the dynamics), the measured torque before the sensor and the
            impedance torque ``I theta'' + B theta' + K theta``.
        """
        d = np.asarray(drive, float)
        tv = np.asarray(voluntary, float)
        if d.shape != tv.shape or d.ndim != 1:
            raise ValueError(f"drive and voluntary torque must be 1-D of equal length, got {d.shape}, {tv.shape}")
        A, B = closed_loop(joint, apparatus)
        c = apparatus.coupling(joint)
        w, d_dot = c.drive_input(d, fs)
        w = w + tv
        Ad, G0, G1 = foh(A, B, 1.0 / fs)
        num, den = transfer_coefficients(Ad, G0, G1)
        # x_i = num[i, 0](z) / den(z) w: the 3-tap numerators first, then the recursive part once for both
        V = np.multiply.outer(w, num[:, 0, 0])
        V[1:] += np.multiply.outer(w[:-1], num[:, 0, 1])
        V[2:] += np.multiply.outer(w[:-2], num[:, 0, 2])
        X = sps.lfilter([1.0], den, V, axis=0)
        theta, vel = X[:, 0].copy(), X[:, 1].copy()
        acc = A[1, 0] * theta + A[1, 1] * vel + B[1, 0] * w
        I, Bv, K = joint.coefficients()
        return Response(angle=theta, velocity=vel, acceleration=acc,
                        torque_measured=c.torque(d, d_dot, theta, vel),
                        torque_impedance=I * acc + Bv * vel + K * theta)
