"""Backend ``stepping``: the analytic family's time-stepping path for a nonlinear plant.

A reflex pathway (:mod:`sims.reflex_stretch`) or a stiffness that depends on the angle
(:mod:`sims.joint_position_dependent`) makes the limb nonlinear, which the exact linear backends (``lti``,
``ltv``) cannot integrate. The plant is split into the linear part they do integrate exactly and a
nonlinear torque ``n(t)``::

    I theta'' + B(t) theta' + K(t) theta + n(t) = T_a + T_v,
    n(t) = T_r(t) + R(theta, theta')     (reflex torque + the joint's remainder, e.g. P(theta) - K(0) theta)

Integration scheme (exponential integrator with a first-order hold of the nonlinear torque):

- the linear part is stepped exactly as in backend ``ltv`` (:func:`sims.backend_ltv.step_coefficients`,
  the exponential midpoint rule for a time-varying K(t), exact for constant coefficients) with every
  input, ``n`` included, held linearly between samples;
- the record is cut into windows of at most ``d`` steps, ``d`` the reflex delay in whole steps: the reflex
  torque over a window depends only on velocities before it, so it is computed ahead
  (:class:`sims.reflex_stretch.ReflexStepper`: the rectified delayed velocity through the activation
  low-pass discretized exactly for a linearly held input) and enters the window as a known input;
- the joint's instantaneous remainder ``R`` is iterated to convergence within each window (Picard: the
  window is simulated with a guess of ``R`` at its samples, ``R`` recomputed from the states, until the
  largest change is below 1e-10 of its size); a window that does not converge is halved, down to one step.

So the scheme is the implicit exponential trapezoidal rule for ``R`` and exact for the reflex's held
input: second order in the step (tests/test_reflex_sims.py checks it against the same trial at eight
times the rate), and with no reflex torque and a linear joint it is backend ``ltv`` to rounding.

References
----------
Hochbruck, M. & Ostermann, A. (2010). Exponential integrators. Acta Numerica 19, 209-286 (Sec. 2.2:
exponential quadrature with a linearly interpolated nonlinearity; Sec. 5: iterated implicit schemes).
"""
from __future__ import annotations

import dataclasses
from typing import Callable, ClassVar

import numpy as np
from jointbench.core.lazy import scipy_signal as sps

from jointbench.core.errors import ConfigError
from jointbench.sims.registries import BACKENDS
from jointbench.sims.backend import Backend, Response
from jointbench.sims.backend_ltv import step_weights
from jointbench.sims.reflex_stretch import ReflexStepper

#: longest window (steps) when no reflex delay bounds it
WINDOW = 256
#: the iteration of the joint's remainder stops when its largest change is below this fraction of (1 N.m plus) its
#: largest value: about 5e5 times the rounding of the remainder (``eps``, 2.2e-16), so a converged window solves
#: the implicit scheme to about ten digits, far below the scheme's own error (the tests bound it at 1e-3 relative
#: at 1 kHz)
TOL = 1e-10
#: most Picard iterations in a window before it is halved: a bound on the work, not the stopping rule (the test
#: suite's position-dependent joints converge within 14); a window that needs more converges too slowly, and the
#: iteration contracts faster on a shorter window
MAX_ITER = 40
#: a window that converges within this many iterations lets the next one double (up to the longest window): the
#: contraction is then strong enough for a longer window
GROW_WITHIN = 3


def _recursion(E, v0: np.ndarray, v1: np.ndarray, x0: tuple[float, float]) -> tuple[np.ndarray, np.ndarray]:
    """States of ``x_k+1 = E_k x_k + v_k`` over one window, step by step in plain floats (a window is at
    most a few hundred steps: faster than the blockwise :func:`sims.backend_ltv.affine_recursion`, and the
    same arithmetic as its short path)."""
    e00, e01, e10, e11 = (c.tolist() for c in E)
    w0, w1 = v0.tolist(), v1.tolist()
    x, y = float(x0[0]), float(x0[1])
    xs, ys = [x], [y]
    for k in range(len(w0)):
        x, y = e00[k] * x + e01[k] * y + w0[k], e10[k] * x + e11[k] * y + w1[k]
        xs.append(x)
        ys.append(y)
    return np.array(xs), np.array(ys)


def _recursion_constant(E, v0: np.ndarray, v1: np.ndarray, x0: tuple[float, float]) -> tuple[np.ndarray, np.ndarray]:
    """:func:`_recursion` for a constant ``E`` (a time-invariant linear part) as four recursive filters:
    ``x = (I - E z^-1)^-1 (x_0 delta + z^-1 v)`` with ``(I - E z^-1)^-1 = adj / det``,
    ``det = 1 - tr(E) z^-1 + det(E) z^-2`` (:func:`scipy.signal.lfilter`; same numbers to rounding)."""
    e00, e01, e10, e11 = (float(c[0]) for c in E)
    den = np.array([1.0, -(e00 + e11), e00 * e11 - e01 * e10])
    s0 = np.concatenate([[x0[0]], v0])
    s1 = np.concatenate([[x0[1]], v1])
    S = np.vstack([s0, s1])
    F = sps.lfilter([1.0], den, S, axis=1)            # the common denominator once for both inputs
    f0, f1 = F
    x = f0.copy()
    x[1:] += -e11 * f0[:-1] + e01 * f1[:-1]
    y = f1.copy()
    y[1:] += e10 * f0[:-1] - e00 * f1[:-1]
    return x, y


def _stepper(reflex, fs: float, n: int, v_before: float):
    if reflex is None:
        return None
    if hasattr(reflex, "stepper"):
        return reflex.stepper(fs, n, v_before)
    return ReflexStepper(reflex, fs, n, 0.0, v_before)


@BACKENDS.register("stepping")
class SteppingBackend(Backend):
    """Time stepping of a nonlinear plant with the exact linear steps of ``ltv`` (module docstring).

    References
    ----------
    Kearney, Stein & Parameswaran 1997 (the reflex pathway); Hochbruck & Ostermann 2010 (the scheme).
    """

    name: ClassVar[str] = "stepping"
    steps: ClassVar[bool] = True

    def respond(self, experiment, drive, voluntary, x0=(0.0, 0.0)) -> Response:
        return self.run(experiment.joint, experiment.apparatus, drive, voluntary, experiment.fs_sim, x0=x0,
                        reflex=experiment.reflex)

    def run(self, joint, apparatus, drive: np.ndarray, voluntary: np.ndarray, fs: float,
            x0: tuple[float, float] = (0.0, 0.0), reflex=None) -> Response:
        """Simulate at ``fs`` Hz from the state ``x0`` (see the module docstring).

        Returns
        -------
        Response
            As backend ``ltv``, with ``torque_parts`` ``intrinsic_torque`` and ``reflex_torque`` when there
            is a reflex pathway (they add up to ``torque_impedance``).
        """
        d = np.asarray(drive, float)
        tv = np.asarray(voluntary, float)
        if d.shape != tv.shape or d.ndim != 1 or len(d) < 2:
            raise ValueError(f"drive and voluntary torque must be 1-D of equal length >= 2, got {d.shape}, {tv.shape}")
        c = apparatus.coupling(joint)
        lin = LinearSteps.of(joint, c, len(d), 1.0 / fs)
        w_lin, d_dot = c.drive_input(d, fs)
        remainder = getattr(joint, "remainder", None) if getattr(joint, "nonlinear", False) else None
        march = _March(lin, w_lin + tv, x0, remainder, reflex, fs)
        march.run()
        theta, vel, R = march.theta, march.vel, march.R
        Tr_all = march.refl.torque if march.refl is not None else np.zeros(len(d))
        I, B, K = joint.coefficients_at(lin.t)
        t_a = c.torque(d, d_dot, theta, vel)
        acc = (t_a + tv - B * vel - K * theta - R - Tr_all) / I
        intrinsic = I * acc + B * vel + K * theta + R
        parts = {"intrinsic_torque": intrinsic, "reflex_torque": Tr_all} if march.refl is not None else {}
        return Response(angle=theta, velocity=vel, acceleration=acc, torque_measured=t_a,
                        torque_impedance=intrinsic + Tr_all, torque_parts=parts)


@dataclasses.dataclass(frozen=True, eq=False)
class LinearSteps:
    """The exact steps of the linear part (backend ``ltv``'s exponential midpoint rule), every input held
    linearly between samples: ``x_k+1 = E_k x_k + v_k`` with ``v_k = a_k w_k + b_k w_k+1`` per state
    component (``a0, b0`` for the angle, ``a1, b1`` for the velocity; backend ltv: columns 1 of J1 and J2 / I).

    Attributes
    ----------
    t : ndarray
        The sample times.
    E : tuple of ndarray
        The transitions' four components, per step.
    a0, b0, a1, b1 : ndarray
        The input weights, per step.
    recursion : callable
        :func:`_recursion_constant` for a time-invariant linear part, else :func:`_recursion`.
    """

    t: np.ndarray
    E: tuple
    a0: np.ndarray
    b0: np.ndarray
    a1: np.ndarray
    b1: np.ndarray
    recursion: Callable

    @classmethod
    def of(cls, joint, coupling, n: int, h: float) -> "LinearSteps":
        """The steps of ``n`` samples at step ``h`` (:func:`sims.backend_ltv.step_weights`)."""
        t, Im, p, q, E, (J1_01, J1_11, J2_01, J2_11) = step_weights(joint, coupling, n, h)
        constant = bool(np.all(p == p[0]) and np.all(q == q[0]) and np.all(Im == Im[0]))
        return cls(t=t, E=E, a0=(J1_01 - J2_01 / h) / Im, b0=J2_01 / h / Im, a1=(J1_11 - J2_11 / h) / Im,
                   b1=J2_11 / h / Im, recursion=_recursion_constant if constant else _recursion)

    def states(self, k0: int, w: np.ndarray, x0: tuple[float, float]) -> tuple[np.ndarray, np.ndarray]:
        """Angle and velocity at the samples ``k0 ... k0 + W`` from the state ``x0`` at ``k0``, for the input
        ``w`` at the same samples (``W + 1`` of them)."""
        sl = slice(k0, k0 + len(w) - 1)
        Ek = tuple(e[sl] for e in self.E)
        v0 = self.a0[sl] * w[:-1] + self.b0[sl] * w[1:]
        v1 = self.a1[sl] * w[:-1] + self.b1[sl] * w[1:]
        return self.recursion(Ek, v0, v1, x0)


class _March:
    """The integration of one record, window by window (module docstring): the exact linear steps, the known
    input, the reflex pathway's stepper, and the states and the joint's remainder so far."""

    def __init__(self, lin: LinearSteps, w_lin: np.ndarray, x0: tuple[float, float], remainder, reflex, fs: float):
        n = len(w_lin)
        self.lin, self.w_lin, self.remainder, self.h = lin, w_lin, remainder, 1.0 / fs
        self.theta, self.vel = np.empty(n), np.empty(n)
        self.theta[0], self.vel[0] = float(x0[0]), float(x0[1])
        self.R = np.zeros(n)
        if remainder is not None:
            self.R[0] = float(remainder(self.theta[:1], self.vel[:1])[0])
        self.refl = _stepper(reflex, fs, n, self.vel[0])

    def run(self) -> None:
        """Every window, from the longest (:data:`WINDOW`, at most the reflex delay) down: a window whose remainder
        does not converge is halved (:class:`ConfigError` at one step), one that converges quickly lets the next
        one double (:data:`GROW_WITHIN`)."""
        n = len(self.w_lin)
        w_max = min(WINDOW, self.refl.lookahead) if self.refl is not None else WINDOW
        width, k0 = w_max, 0
        while k0 < n - 1:
            W = min(width, n - 1 - k0)
            if self.refl is not None:
                self.refl.advance(k0 + W + 1, self.vel)   # needs the velocity up to k0 + W - d <= k0: known
                w_in = self.w_lin[k0:k0 + W + 1] - self.refl.torque[k0:k0 + W + 1]
            else:
                w_in = self.w_lin[k0:k0 + W + 1]
            done = self.window(k0, w_in)
            if done is None:
                if W == 1:
                    raise ConfigError(f"backend 'stepping': the joint's angle-dependent torque does not converge "
                                      f"within one step at t = {k0 * self.h:.4g} s; raise fs_sim")
                width = max(1, W // 2)
                continue
            xs, ys, guess, iterations = done
            self.theta[k0 + 1:k0 + W + 1], self.vel[k0 + 1:k0 + W + 1] = xs[1:], ys[1:]
            if self.remainder is not None:
                self.R[k0 + 1:k0 + W + 1] = guess
                if iterations <= GROW_WITHIN:
                    width = min(w_max, 2 * width)
            k0 += W

    def window(self, k0: int, w_in: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, int] | None:
        """Angle and velocity at the samples ``k0 ... k0 + W`` for the known input ``w_in`` there, with the joint's
        remainder at ``k0 + 1 ... k0 + W`` iterated to convergence (Picard, from its linear extrapolation; at most
        :data:`MAX_ITER` iterations, until :data:`TOL`): ``(angle, velocity, remainder, iterations)``, or None
        when it does not converge."""
        R, W = self.R, len(w_in) - 1
        x0 = (self.theta[k0], self.vel[k0])
        slope = R[k0] - R[k0 - 1] if k0 >= 1 else 0.0
        guess = R[k0] + slope * np.arange(1, W + 1)
        if self.remainder is None:
            xs, ys = self.lin.states(k0, w_in - np.concatenate([[R[k0]], guess]), x0)
            return xs, ys, guess, 1
        for it in range(MAX_ITER):
            xs, ys = self.lin.states(k0, w_in - np.concatenate([[R[k0]], guess]), x0)
            new = self.remainder(xs[1:], ys[1:])
            change = float(np.max(np.abs(new - guess)))
            if not np.isfinite(change):
                return None
            if change <= TOL * (1.0 + float(np.max(np.abs(new)))):
                return xs, ys, guess, it + 1
            guess = new
        return None
