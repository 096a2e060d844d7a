"""The physics backend's path for a nonlinear plant: a reflex pathway, a stiffness that depends on the angle.

The MuJoCo model is the linear one of :mod:`sims.backend_mujoco_models` (the joint's linear part, K(t)
and B(t), as controls); the nonlinear torque ``n = T_r + R(theta, theta')`` (reflex torque and the
joint's remainder, as in :mod:`sims.backend_stepping`) is applied through the voluntary-torque motor,
``T_v - n``. The trial is rolled out in windows of at most ``d`` steps (``d`` the reflex delay in
steps; 256 without a reflex):

- the reflex torque of a window needs the limb's velocity at the sample instants up to ``d`` steps
  before, the mean of MuJoCo's two staggered velocities around each instant (as the backend reports
  the velocity): known before the window, so it is computed ahead
  (:class:`sims.reflex_stretch.ReflexStepper`) and enters as a control;
- MuJoCo applies a force that depends on the positions at the step's start (semi-implicit Euler), so the
  joint's remainder at step k is ``R(theta_k, theta'_k)`` with the step's starting state; within a window
  it is iterated to convergence (the window rolled out again from the same state with the remainder
  of the last rollout's states, until the largest change is below 1e-10 of its size), which is what a
  step-by-step evaluation would give, at the speed of ``mujoco.rollout``.

References
----------
MuJoCo documentation, ``mujoco.rollout`` and "Computation / Numerical integration"; Kearney, Stein &
Parameswaran 1997 (the reflex pathway).
"""
from __future__ import annotations

import numpy as np

from jointbench.core.errors import ConfigError
from jointbench.sims.backend_stepping import GROW_WITHIN, MAX_ITER, TOL, WINDOW   # the same windows and iteration
from jointbench.sims.reflex_stretch import ReflexStepper


def rollout_nonlinear(mujoco, model, data, s0: np.ndarray, ctrl: np.ndarray, exp, vol_column: int):
    """Roll ``ctrl`` out window by window with the nonlinear torque added to column ``vol_column``.

    Returns ``(state, sensordata, R, Tr)``: MuJoCo's state and sensor rows after every step (as
    ``mujoco.rollout.rollout`` gives them for one trajectory), and the joint's remainder and the reflex
    torque applied at every step (N·m).
    """
    from mujoco import rollout

    n = len(ctrl)
    nq = model.nq
    h = 1.0 / exp.fs_sim
    joint = exp.joint
    remainder = getattr(joint, "remainder", None) if getattr(joint, "nonlinear", False) else None
    refl = ReflexStepper(exp.reflex, exp.fs_sim, n, 0.0, float(s0[1 + nq])) if exp.reflex is not None else None
    w_max = min(WINDOW, refl.lookahead) if refl is not None else WINDOW
    state = np.empty((n, len(s0)))
    sens = np.empty((n, model.nsensordata))
    R = np.zeros(n)
    vmid = np.zeros(n)                     # velocity at the sample instants (mean of the staggered ones)
    theta0, v0 = float(s0[1]), float(s0[1 + nq])
    if remainder is not None:
        R[0] = float(remainder(np.array([theta0]), np.array([v0]))[0])
    base = ctrl[:, vol_column].copy()
    start = s0.copy()
    width, k0 = w_max, 0
    while k0 < n:
        W = min(width, n - k0)
        if refl is not None:
            refl.advance(k0 + W, vmid)     # needs the velocity up to k0 + W - 1 - d <= k0 - 1: known
            Tr = refl.torque[k0:k0 + W]
        else:
            Tr = 0.0
        slope = R[k0] - R[k0 - 1] if k0 >= 1 else 0.0
        guess = R[k0] + slope * np.arange(1, W)          # remainder at steps k0 + 1 ... k0 + W - 1
        converged = remainder is None
        for it in range(MAX_ITER if remainder is not None else 1):
            c = ctrl[k0:k0 + W].copy()
            c[:, vol_column] = base[k0:k0 + W] - Tr - np.concatenate([[R[k0]], guess])
            st, sd = rollout.rollout(model, data, start, c[None])
            st, sd = st[0], sd[0]
            if remainder is None:
                break
            new = remainder(st[:-1, 1], st[:-1, 1 + nq])
            change = float(np.max(np.abs(new - guess))) if W > 1 else 0.0
            if not np.isfinite(change):
                break
            if change <= TOL * (1.0 + (float(np.max(np.abs(new))) if W > 1 else 0.0)):
                converged = True
                break
            guess = new
        if not converged:
            if W == 1:
                raise ConfigError(f"backend 'mujoco': the joint's angle-dependent torque does not converge within "
                                  f"one step at t = {k0 * h:.4g} s; raise fs_sim")
            width = max(1, W // 2)
            continue
        state[k0:k0 + W], sens[k0:k0 + W] = st, sd
        v_start = np.concatenate([[start[1 + nq]], st[:, 1 + nq]])        # staggered velocities k0 ... k0 + W
        vmid[k0:k0 + W] = 0.5 * (v_start[:-1] + v_start[1:])
        if remainder is not None:
            R[k0 + 1:k0 + W] = guess
            if k0 + W < n:
                R[k0 + W] = float(remainder(st[-1:, 1], st[-1:, 1 + nq])[0])
            if it + 1 <= GROW_WITHIN:
                width = min(w_max, 2 * width)
        start = st[-1].copy()
        k0 += W
    return state, sens, R, (refl.torque if refl is not None else np.zeros(n))
