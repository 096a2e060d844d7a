"""The simulation backend interface: what a backend supports, how it simulates, the truth it provides.

A backend integrates the limb held by the apparatus; everything before it (perturbation, voluntary
torque) and after it (sensors, noise, acquisition, the truth's frozen transfer function) is shared code
in :func:`sims.simulate`, so two backends given the same experiment and seed differ only by their
physics. A backend is a class registered in :data:`sims.BACKENDS` that derives :class:`Backend`:

- :meth:`Backend.check` (what it supports): raise :class:`~jointbench.core.errors.ConfigError` when it cannot
  simulate an experiment (a feature it does not model, a model it cannot build, a step that is unstable).
  :class:`sims.Experiment` calls it while validating, so a config error surfaces before any run;
- :meth:`Backend.respond` (simulate): the limb's angle, velocity, acceleration, the torque the load cell
  sees and the impedance torque, at the simulation rate, as a :class:`Response`;
- the truth it can provide: :attr:`Response.extra` holds noise-free signals only this backend knows
  (e.g. the gravity torque of the physics engine); they are acquired like the measurements and join
  ``trial.truth.signals``. The parameters (I, B, K) and the frozen transfer function of the truth come
  from the joint model and the apparatus' linear coupling, the same for every backend.

Registered: ``analytic`` (the default: ``lti`` when it applies, else ``ltv``; ``stepping`` for a
nonlinear plant: a reflex pathway, a stiffness that depends on the angle), ``lti``, ``ltv``, ``stepping``
and ``mujoco`` (a physics engine; imported only when used).
"""
from __future__ import annotations

import dataclasses
from typing import Any, ClassVar, Mapping

import numpy as np

from jointbench.core.errors import Incompatible
from jointbench.sims.registries import BACKENDS


@dataclasses.dataclass(frozen=True)
class Response:
    """What a backend returns: signals at the simulation rate, before any sensor model.

    Attributes
    ----------
    angle, velocity, acceleration : ndarray
        theta (rad), theta' (rad/s), theta'' (rad/s²) of the limb, the acceleration from the dynamics.
    torque_measured : ndarray
        The torque the load cell sees (N·m), T_m of Fig. 1 (position servo) or the applied torque.
    torque_impedance : ndarray
        The limb's impedance torque I theta'' + B theta' + K theta (N·m), free of noise.
    angle_measured : ndarray or None
        The angle the encoder sees when it is not the limb's (a handle with its own dynamics); None: the
        drive signal for an ideal handle, else the limb's angle.
    extra : mapping
        Further noise-free signals at the simulation rate (name -> array), added to the truth's signals.
    torque_parts : mapping
        Parts of the impedance torque (name -> array, e.g. ``intrinsic_torque`` and ``reflex_torque`` of
        a joint with a reflex pathway): the truth's signals, through the torque sensor's filter like the
        torque they add up to.
    """

    angle: np.ndarray
    velocity: np.ndarray
    acceleration: np.ndarray
    torque_measured: np.ndarray
    torque_impedance: np.ndarray
    angle_measured: np.ndarray | None = None
    extra: Mapping[str, np.ndarray] = dataclasses.field(default_factory=dict)
    torque_parts: Mapping[str, np.ndarray] = dataclasses.field(default_factory=dict)


def nonlinear_parts(experiment) -> str:
    """What makes the plant nonlinear ('' when nothing): a reflex pathway, a state-dependent joint. Such an
    experiment needs a backend with a time-stepping path (``analytic`` chooses ``stepping``)."""
    parts = []
    if getattr(experiment, "reflex", None) is not None:
        parts.append("a reflex pathway")
    if getattr(experiment.joint, "nonlinear", False):
        parts.append(f"joint model '{experiment.joint.model}' (its coefficients depend on the angle)")
    return " and ".join(parts)


class Backend:
    """Base class of the simulation backends (see the module docstring).

    Subclasses implement :meth:`run` (the analytic integrators) or override :meth:`respond`.
    """

    name: ClassVar[str] = ""
    #: whether the backend integrates a nonlinear plant (:func:`nonlinear_parts`) by time stepping
    steps: ClassVar[bool] = False

    def check(self, experiment) -> None:
        """Raise :class:`ConfigError` (message without location) if this backend cannot simulate it."""
        reason = analytic_limits(experiment)
        if reason:
            raise Incompatible(f"backend '{self.name}' cannot simulate this experiment: {reason}")
        nonlinear = nonlinear_parts(experiment)
        if nonlinear and not self.steps:
            raise Incompatible(f"backend '{self.name}' integrates a linear plant; this experiment has {nonlinear}: "
                               f"use 'analytic' (it then steps in time, backend 'stepping') or 'mujoco'")

    def respond(self, experiment, drive: np.ndarray, voluntary: np.ndarray,
                x0: tuple[float, float] = (0.0, 0.0)) -> Response:
        """The limb and apparatus driven by ``drive`` and ``voluntary`` (one sample per simulation step),
        from the state ``x0`` = (theta, theta') at t = 0."""
        kw = {} if tuple(x0) == (0.0, 0.0) else {"x0": x0}
        return self.run(experiment.joint, experiment.apparatus, drive, voluntary, experiment.fs_sim, **kw)

    def run(self, joint, apparatus, drive, voluntary, fs, **kw) -> Response:  # pragma: no cover - abstract
        raise NotImplementedError


def analytic_limits(experiment) -> str:
    """What the linear models leave out, if the experiment asks for it ('' when nothing)."""
    if getattr(experiment, "gravity", None) is not None:
        return ("gravity (the tau_g(theta) of Xu & Hollerbach's eq. 1) is not in the linear models; "
                "use backend 'mujoco'")
    dyn = getattr(experiment.apparatus, "dynamics", None)
    if dyn:
        return (f"the analytic handle is ideal (its angle is the drive); its {dyn} need backend 'mujoco' "
                f"(or leave them out)")
    return ""


def lti_applies(experiment) -> str:
    """'' when the exact ``lti`` backend applies, else why not."""
    exp = experiment
    c = exp.apparatus.coupling(exp.joint)
    if not (getattr(exp.joint, "time_invariant", False) and hasattr(exp.joint, "state_space")):
        return f"joint model '{exp.joint.model}' varies in time (or has no state space)"
    if c.g_d or c.b_a:
        return f"the apparatus '{exp.apparatus.kind}' acts through the drive's derivative or a damping"
    if exp.voluntary.moving:
        return "a voluntary movement starts from a moving state"
    return ""


@BACKENDS.register("analytic")
class AnalyticBackend(Backend):
    """The analytic simulators: ``lti`` (exact first-order hold) when it applies, else ``ltv``
    (exponential midpoint rule). Both integrate the linear model of the joint and the apparatus'
    linear coupling; neither models gravity or a handle's own dynamics."""

    name: ClassVar[str] = "analytic"
    steps: ClassVar[bool] = True

    def chosen(self, experiment) -> str:
        """The analytic backend that simulates ``experiment``: 'lti' or 'ltv', or 'stepping' for a
        nonlinear plant (:func:`nonlinear_parts`)."""
        if nonlinear_parts(experiment):
            return "stepping"
        return "ltv" if lti_applies(experiment) else "lti"

    def respond(self, experiment, drive, voluntary, x0=(0.0, 0.0)) -> Response:
        return BACKENDS.get(self.chosen(experiment))().respond(experiment, drive, voluntary, x0)


def resolve(backend: str | Any) -> Backend:
    """The backend object for a name of :data:`sims.BACKENDS` (or an object with ``respond``/``run``)."""
    if isinstance(backend, str):
        return BACKENDS.get(backend)()
    return backend


# --------------------------------------------------------------------------------- simulation timing
_RECORDERS: list[list] = []


class SimulationLog(list):
    """Entries ``(backend, seconds, reused)``, one per :func:`sims.simulate` call inside
    :func:`record_simulations`; ``reused`` is True when the response came from :mod:`sims.reuse`."""

    @property
    def seconds(self) -> float:
        return float(sum(e[1] for e in self))


class record_simulations:
    """Context manager collecting the time of every trial simulated inside it (for the harness' reports).

    >>> with record_simulations() as log:   # doctest: +SKIP
    ...     simulate(experiment, 0)
    >>> log.seconds
    """

    def __enter__(self) -> SimulationLog:
        self.log = SimulationLog()
        _RECORDERS.append(self.log)
        return self.log

    def __exit__(self, *exc) -> None:
        _RECORDERS.remove(self.log)


def record(backend: str, seconds: float, reused: bool = False) -> None:
    """Tell the recorders open now (:class:`record_simulations`) that ``backend`` simulated for ``seconds`` (or reused a
    response)."""
    for log in _RECORDERS:
        log.append((backend, seconds, bool(reused)))
