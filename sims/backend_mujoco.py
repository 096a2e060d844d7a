"""Backend ``mujoco``: the joint models as MuJoCo models, for apparatus effects the linear models leave out.

The models (:mod:`sims.backend_mujoco_models`) are generated with ``dm_control.mjcf`` and compiled with
``mujoco.MjModel.from_xml_string`` from its ``to_xml_string()``. One trial is one call of
``mujoco.rollout.rollout`` with the whole control sequence (K(t), B(t), the drive input and the
voluntary torque, one row per step), so the 100 000-odd steps of a trial run in C without a Python
loop. ``mujoco`` and ``dm_control`` are imported when the backend is first used, never by ``import jointbench.sims``.

Why compile the XML with mujoco rather than use ``dm_control.mjcf.Physics``: dm_control's ``Physics``
wraps every field of ``MjModel`` by name and breaks whenever MuJoCo renames one (with mujoco 4.0.0 and
dm-control 1.0.50, ``Physics.from_mjcf_model`` fails on ``'MjModel' object has no attribute
'flex_vertedge'``; dm_control issue 500 is the same break for ``flex_xvert0`` in 2024). The MJCF builder
and ``to_xml_string`` only write XML and work with every MuJoCo 3.17 - 4.0, so the project uses the
newest pair and depends on no ``Physics`` internals (tests/test_backend_mujoco.py checks both facts).

Integration (``implicitfast``, one step per simulation sample):

- semi-implicit Euler in the positions: a force that depends on the angle and the control at t_k
  (the servo K_a (theta_r - theta), the joint's K(t) theta, gravity) acts like a leapfrog step, second
  order; the controls are therefore sampled at the step's start;
- the velocity gains (the joint's B(t), the servo's B_a, the contact damping b_c) are implicit: stable
  at any step (b_c / I = 3300 /s at the wrist) and evaluated at the step's end, i.e. at the middle of
  the leapfrog's staggered velocity; a servo's velocity feed-forward (B_a theta_r') is therefore
  sampled at the step's middle (:meth:`MujocoBackend.controls`);
- the implicit damping acts at the step's end, half a step after the forces of the positions: the
  simulated limb behaves as if its inertia were I + B h/2 (0.07 % for Westwick's elbow at 5 kHz, 0.4 %
  for Xu's elbow at 2 kHz; 3.7 % for the calibration arm's B = 10.1 at 2 kHz, where FSEWLS then reads
  I 1.8 % high instead of 0.2 %); a higher fs_sim shrinks it in proportion;
- stiffness is never implicit: the step must satisfy (roughly) K h² / I < 4 + 2 B h / I for the stiffest
  frozen K(t) + K_a. :meth:`MujocoBackend.check` computes the one-step transition matrix of the model
  (``mujoco.mjd_transitionFD``) at the stiffest, least damped instant and refuses a step whose
  spectral radius exceeds 1, naming the largest stable step (bisection); after every trial
  ``data.warning`` is checked (MuJoCo resets a diverging simulation to zero with only a warning), and a
  diverged trial is an error, never zeros.

What is read where: the angle from a ``jointpos`` sensor (the handle's from a ``tendonpos`` sensor),
the torque of a torque drive or position servo from an ``actuatorfrc`` sensor at the step's start t_k;
a servo damping's part of it is moved to t_k as well (the sensor saw the feed-forward at the step's
middle and the staggered velocity theta'_k-1/2: the damping part becomes B_a (theta_r'(t_k) - theta'(t_k)),
theta'(t_k) the mean of the two staggered velocities). The contact torque of the wrist is the torque the handle
applies to the hand over each step, from the hand's own equation of motion, I theta'' + B theta' + K theta - T_v -
tau_g: reading it from
the contact's deflection (tendon sensors, k_c delta + b_c delta') would multiply the integrator's error
in the hand's angle by |Z_c / Z_w|, about 100 near the wrist's resonance (VAF 97.6 % against the
analytic backend instead of 99.99 %).

References
----------
Todorov, Erez & Tassa 2012 (MuJoCo); MuJoCo documentation: "Computation / Numerical integration",
``mujoco.rollout``, ``mjd_transitionFD``.
"""
from __future__ import annotations

import logging
import math
from typing import ClassVar

import numpy as np

from jointbench.core.errors import ConfigError
from jointbench.sims.registries import BACKENDS
from jointbench.sims.apparatus import derivative
from jointbench.sims.backend import Backend, Response, nonlinear_parts
from jointbench.sims.backend_mujoco_models import CONTROLS, HandleServo, build, mjcf_module

_LOG = logging.getLogger(__name__)
_CACHE: dict = {}          # structural key -> (MjModel, xml)
_STABLE_TOL = 1e-7         # spectral radius above 1 + this is unstable (an undamped mode sits at exactly 1)


class SimulationDiverged(ConfigError):
    """A MuJoCo trial diverged: the step is too large for the stiffest instant of the model."""


_READY = False


def _mujoco():
    """``mujoco``, with dm_control loaded and MuJoCo's warnings routed to logging.

    MuJoCo's default warning handler appends to ``MUJOCO_LOG.TXT`` in the working directory (and
    dm_control's to absl); a diverging trial is an error here anyway (:meth:`MujocoBackend.respond`
    reads ``data.warning``), so the text goes to the ``sims.backend_mujoco`` logger at debug level.
    """
    global _READY
    try:
        import mujoco
        from mujoco import rollout  # noqa: F401 - a submodule, loaded here
    except ImportError as exc:  # pragma: no cover - depends on the installation
        raise ConfigError(f"backend 'mujoco' needs the packages mujoco and dm-control "
                          f"(pip install 'jointbench[mujoco]'): {exc}") from None
    if not _READY:
        mjcf_module()   # dm_control installs its own handler on import: install ours after it
        mujoco.set_mju_user_warning(lambda text: _LOG.debug("MuJoCo: %s", text))
        _READY = True
    return mujoco


def _key(exp, timestep: float, integrator: str) -> tuple:
    """What the compiled model depends on (the time-varying K(t), B(t) are controls, not in it)."""
    app = exp.apparatus
    I = float(np.asarray(exp.joint.coefficients_at(np.zeros(1))[0])[0])
    if app.kind == "handle":
        servo = HandleServo.of(app, timestep)
        coupling = (getattr(exp.joint, "contact", None), servo)
    else:
        c = app.coupling(exp.joint)
        coupling = (c.k_a, c.b_a)
    return (app.kind, type(exp.joint).__name__, I, coupling, exp.gravity, float(timestep), integrator)


def compiled(exp, timestep: float | None = None, integrator: str = "implicitfast"):
    """The compiled ``mujoco.MjModel`` of ``exp`` (cached by structure) and its XML."""
    mujoco = _mujoco()
    h = 1.0 / exp.fs_sim if timestep is None else timestep
    key = _key(exp, h, integrator)
    hit = _CACHE.get(key)
    if hit is None:
        root = build(exp.joint, exp.apparatus, exp.gravity, h, integrator)
        xml = root.to_xml_string()
        try:
            model = mujoco.MjModel.from_xml_string(xml)
        except ValueError as exc:   # the compiler's message, one line
            raise ConfigError(f"backend 'mujoco' cannot compile the model of joint '{exp.joint.model}' on "
                              f"'{exp.apparatus.kind}': {str(exc).splitlines()[0]}") from None
        # no contacts, limits or equality constraints in these models: skip the constraint pipeline and
        # its island search (same numbers, about 10 % less time per step)
        model.opt.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_CONSTRAINT) | int(mujoco.mjtDisableBit.mjDSBL_ISLAND)
        if len(_CACHE) > 64:
            _CACHE.clear()
        hit = _CACHE[key] = (model, xml)
    return hit


def _worst_controls(exp, nu: int, names: tuple[str, ...]) -> np.ndarray:
    """Controls at the stiffest, least damped frozen instant of the joint (drive and voluntary 0)."""
    t = np.linspace(0.0, exp.duration, 4001)
    _, B, K = exp.joint.coefficients_at(t)
    ctrl = np.zeros(nu)
    ctrl[names.index("stiffness")] = max(float(np.max(K)), getattr(exp.joint, "stiffness_range", (0, 0))[1])
    ctrl[names.index("damping")] = float(np.min(B))
    return ctrl


def spectral_radius(model, ctrl: np.ndarray, timestep: float) -> float:
    """Largest |eigenvalue| of MuJoCo's one-step transition matrix at rest with controls ``ctrl``."""
    mujoco = _mujoco()
    m = model.__copy__()
    m.opt.timestep = timestep
    d = mujoco.MjData(m)
    d.ctrl[:] = ctrl
    n = 2 * m.nv + m.na
    A = np.zeros((n, n))
    mujoco.mjd_transitionFD(m, d, 1e-6, True, A, None, None, None)
    return float(np.max(np.abs(np.linalg.eigvals(A))))


def largest_stable_step(model, ctrl: np.ndarray, unstable: float) -> float:
    """The largest step below ``unstable`` (s) with spectral radius <= 1 (bisection on a log scale)."""
    lo = unstable
    while spectral_radius(model, ctrl, lo) > 1 + _STABLE_TOL:
        lo /= 4.0
        if lo < 1e-10:
            return 0.0
    hi = unstable
    for _ in range(40):
        mid = math.sqrt(lo * hi)
        if spectral_radius(model, ctrl, mid) > 1 + _STABLE_TOL:
            hi = mid
        else:
            lo = mid
        if hi / lo < 1 + 1e-4:
            break
    return lo


def _stiffest(exp) -> str:
    _, _, K = exp.joint.coefficients_at(np.linspace(0.0, exp.duration, 4001))
    parts = [f"joint stiffness up to {np.max(K):.4g} N.m/rad"]
    app = exp.apparatus
    if app.kind == "position_servo":
        parts.append(f"servo K_a = {app.stiffness:.4g} N.m/rad")
    elif app.kind == "handle":
        k_c = getattr(exp.joint, "contact", (0.0, 0.0))[0]
        parts.append(f"contact k_c = {k_c:.4g} N.m/rad and the handle's servo")
    return ", ".join(parts)


def _step_message(exp, h_max: float) -> str:
    if h_max <= 0:
        return "no stable step was found"
    return (f"the largest stable step is {h_max:.4g} s, i.e. fs_sim >= {1.0 / h_max:.5g} Hz "
            f"(with {_stiffest(exp)})")


@BACKENDS.register("mujoco", tags=("physics",))
class MujocoBackend(Backend):
    """The MuJoCo physics engine (see the module docstring).

    Supports every joint model (``second_order``, ``time_varying`` on a torque drive or position servo;
    ``wrist_contact`` on a handle; ``position_dependent``), gravity (:class:`sims.gravity.Gravity`), a handle
    with its own inertia and servo, and a reflex pathway (:mod:`sims.backend_mujoco_stepping`); not a
    varying inertia.
    """

    name: ClassVar[str] = "mujoco"
    integrator: ClassVar[str] = "implicitfast"

    @classmethod
    def unavailable(cls) -> str | None:
        """Why this backend cannot run in this installation (its packages are an extra), or None."""
        import importlib.util

        missing = [m for m in ("mujoco", "dm_control") if importlib.util.find_spec(m) is None]
        if missing:
            return (f"needs {' and '.join(missing)}, not installed: pip install 'jointbench[mujoco]' (or "
                    f"jointbench[all])")
        return None

    def check(self, experiment) -> None:
        """Build and compile the model, and refuse a step that is unstable at the stiffest instant."""
        exp = experiment
        model, _ = compiled(exp, integrator=self.integrator)
        names = CONTROLS[exp.apparatus.kind]
        ctrl = _worst_controls(exp, model.nu, names)
        h = 1.0 / exp.fs_sim
        if exp.reflex is not None:
            exp.reflex.check(exp.fs_sim, exp.duration, "joint: reflex")
        rho = spectral_radius(model, ctrl, h)
        if rho > 1 + _STABLE_TOL:
            raise ConfigError(f"backend 'mujoco': the step 1/fs_sim = {h:.4g} s is unstable for this model "
                              f"(one-step spectral radius {rho:.4g} > 1); "
                              f"{_step_message(exp, largest_stable_step(model, ctrl, h))}")

    def controls(self, exp, drive: np.ndarray, voluntary: np.ndarray) -> np.ndarray:
        """One row per step, in the actuator order of :data:`CONTROLS`: K(t), B(t), the drive's input to
        the apparatus actuator and the voluntary torque, at the step's start t_k; a velocity feed-forward
        (a servo's damping times the drive's derivative) at the step's middle, where the implicit damping
        it pairs with evaluates the limb's velocity."""
        fs, n = exp.fs_sim, len(drive)
        h = 1.0 / fs
        t = np.arange(n) * h
        _, B, K = exp.joint.coefficients_at(t)
        app = exp.apparatus
        d_dot = derivative(drive, h)
        d_mid = ctrl_mid(d_dot)
        if app.kind == "handle":
            servo = HandleServo.of(app, h)
            u = servo.stiffness * drive + servo.damping * d_mid + servo.inertia * derivative(d_dot, h)
        else:
            c = app.coupling(exp.joint)
            u = c.g * drive + c.g_d * d_mid
        return np.ascontiguousarray(np.column_stack([K, B, u, voluntary]), dtype=float)

    def respond(self, experiment, drive, voluntary, x0=(0.0, 0.0)) -> Response:
        """Simulate one trial with ``mujoco.rollout`` (see the module docstring for what is read where)."""
        mujoco = _mujoco()
        from mujoco import rollout

        exp = experiment
        d = np.asarray(drive, float)
        tv = np.asarray(voluntary, float)
        if d.shape != tv.shape or d.ndim != 1 or len(d) < 2:
            raise ValueError(f"drive and voluntary torque must be 1-D of equal length >= 2, got {d.shape}, {tv.shape}")
        model, _ = compiled(exp, integrator=self.integrator)
        h = 1.0 / exp.fs_sim
        n = len(d)
        ctrl = self.controls(exp, d, tv)
        data = mujoco.MjData(model)
        data.qpos[0], data.qvel[0] = float(x0[0]), float(x0[1])   # the limb's hinge is the first joint
        spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
        s0 = np.empty(mujoco.mj_stateSize(model, spec))
        mujoco.mj_getState(model, data, s0, spec)
        n_extra = 0.0
        if nonlinear_parts(exp):   # a reflex or an angle-dependent joint: window by window (backend_mujoco_stepping)
            from jointbench.sims.backend_mujoco_stepping import rollout_nonlinear

            state, sensordata, R, Tr = rollout_nonlinear(mujoco, model, data, s0, ctrl, exp,
                                                         CONTROLS[exp.apparatus.kind].index("voluntary"))
            n_extra = R + Tr
        else:
            state, sensordata = rollout.rollout(model, data, s0, ctrl[None])
            state, sensordata = state[0], sensordata[0]
        self._raise_if_diverged(exp, model, data, state)
        nq, nv = model.nq, model.nv
        q = np.concatenate([s0[None, 1:1 + nq], state[:-1, 1:1 + nq]])     # at the steps' starts
        v = np.concatenate([s0[None, 1 + nq:1 + nq + nv], state[:, 1 + nq:1 + nq + nv]])   # n + 1 rows
        theta = q[:, 0]
        v0, v1 = v[:-1, 0], v[1:, 0]
        acc = (v1 - v0) / h
        t = np.arange(n) * h
        I, B, K = exp.joint.coefficients_at(t)
        sensor = {name: sensordata[:, model.sensor(name).adr[0]] for name in ("angle", "torque", "handle_angle")
                  if _has_sensor(model, name)}
        tau_g = exp.gravity.torque(theta) if exp.gravity is not None else np.zeros(n)
        impedance = I * acc + B * v1 + K * theta + n_extra   # the forces of the step, damping implicit
        extra = {}
        if exp.gravity is not None:
            extra = {"gravity_torque": tau_g, "gravity_stiffness": exp.gravity.stiffness(theta)}
        if exp.apparatus.kind == "handle":
            measured = impedance - tv - tau_g            # what the handle applies to the hand
            angle_measured = np.array(sensor["handle_angle"])
        else:
            measured = np.array(sensor["torque"])
            c = exp.apparatus.coupling(exp.joint)
            if c.b_a:   # the sensor saw B_a (theta_r'(mid) - theta'_k): resample the damping part at t_k
                d_dot = derivative(d, h)
                measured += c.g_d * (d_dot - ctrl_mid(d_dot)) - c.b_a * (0.5 * (v0 + v1) - v0)
            angle_measured = None
        parts = {"intrinsic_torque": impedance - Tr, "reflex_torque": Tr} if exp.reflex is not None else {}
        return Response(angle=np.array(sensor["angle"]), velocity=0.5 * (v0 + v1), acceleration=acc,
                        torque_measured=measured, torque_impedance=impedance, angle_measured=angle_measured,
                        extra=extra, torque_parts=parts)

    def _raise_if_diverged(self, exp, model, data, state: np.ndarray) -> None:
        """MuJoCo resets a diverging simulation to its initial state with only a warning: fail loudly."""
        mujoco = _mujoco()
        bad = {name: data.warning[int(getattr(mujoco.mjtWarning, name))].number
               for name in ("mjWARN_BADQACC", "mjWARN_BADQVEL", "mjWARN_BADQPOS", "mjWARN_BADCTRL")}
        bad = {k: v for k, v in bad.items() if v}
        finite = bool(np.all(np.isfinite(state)))
        if not bad and finite:
            return
        times = state[:, 0]
        reset = np.flatnonzero(np.diff(times) < 0)
        when = (f" at t = {times[reset[0]]:.4g} s" if len(reset) else "")
        names = ", ".join(k.replace("mjWARN_", "") for k in bad) or "non-finite state"
        ctrl = _worst_controls(exp, model.nu, CONTROLS[exp.apparatus.kind])
        h_max = largest_stable_step(model, ctrl, 1.0 / exp.fs_sim)
        loop = ("; or the reflex loop itself is unstable (delayed velocity feedback: lower the reflex gain)"
                if getattr(exp, "reflex", None) is not None else "")
        raise SimulationDiverged(f"{exp.where}: backend 'mujoco': the simulation diverged{when} ({names}); "
                                 f"{_step_message(exp, h_max)}{loop}")


def ctrl_mid(x: np.ndarray) -> np.ndarray:
    """``x`` at the middles of the steps (mean of the two ends; the last sample repeated)."""
    return np.append(0.5 * (x[:-1] + x[1:]), x[-1])


def _has_sensor(model, name: str) -> bool:
    try:
        model.sensor(name)
    except KeyError:
        return False
    return True
