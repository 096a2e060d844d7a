"""The description of a simulated experiment (pure data) and :func:`simulate`, which runs it.

An :class:`Experiment` holds already-parsed, validated parts: a joint model and a perturbation (picked
from the registries :data:`sims.JOINTS` and :data:`sims.PERTURBATIONS`), the apparatus, the voluntary
torque, the sensor models, the simulation rate and length, and the acquisition steps. It knows nothing
of how the dynamics are integrated: :func:`simulate` hands the limb, the apparatus and the input signals
to the experiment's backend (:mod:`sims.backend`; ``"analytic"``: exact first-order hold for
time-invariant joints, exponential midpoint rule for time-varying ones; ``"mujoco"``: a physics engine),
then applies the same sensors and acquisition whatever the backend.

References
----------
Westwick & Perreault 2012, Fig. 1 and eqs. 3-8 (Sec. II-A); Sec. IV (the experiment simulated here).
"""
from __future__ import annotations

import dataclasses
import math
import time
from typing import Any, Callable, Literal, Mapping

import numpy as np

from jointbench.core.errors import ConfigError, Incompatible
from jointbench.core.schema import Problems, param, parse, parse_tagged, tagged
from jointbench.core.signal import decimate, decimate_fft
from jointbench.core.types import Trial
from jointbench.sims.registries import BACKENDS, JOINTS, PERTURBATIONS, REFLEXES
from jointbench.sims import backend as _backend
from jointbench.sims import reuse as _reuse
from jointbench.sims import truth as _truth
from jointbench.sims.apparatus import APPARATUS_KINDS, Apparatus, PositionServo
from jointbench.sims.backend import Response  # noqa: F401 - re-exported (backends import it from here too)
from jointbench.sims.gravity import Gravity
from jointbench.sims.sensors import Sensor, Sensors
from jointbench.sims.voluntary import Voluntary
from jointbench.sims._channels import (  # noqa: F401 - STREAMS re-exported
    STREAMS, detrend_linear, measure, streams, unit_noise)

@dataclasses.dataclass(frozen=True)
class Acquisition:
    """What the data acquisition does to every channel after the sensors, in this order.

    Parameters
    ----------
    detrend : bool
        Remove a least-squares straight line over the whole record (at the simulation rate).
    fs : float or None
        Acquired rate (Hz). None = ``fs_sim``.
    trim : float
        Seconds removed at both ends of the acquired record (filter and start-up transients).
    decimation : {'fir', 'fft'}
        'fir': ``fs`` must divide ``fs_sim`` by a whole factor q; :func:`jointbench.core.signal.decimate`
        (zero-phase FIR anti-alias filter). 'fft': :func:`jointbench.core.signal.decimate_fft` (keep the DFT
        bins below the new Nyquist rate); ``fs · duration`` must be a whole number of samples.

    References
    ----------
    Westwick & Perreault 2012, Sec. IV ("detrended, and then decimated to 500 Hz. Both ends of the
    signals were trimmed"); van de Ruit et al. 2018, Sec. IV-E (decimated in the frequency domain).
    """

    detrend: bool = True
    fs: float | None = param(None, unit="Hz", gt=0, doc="acquired rate; default fs_sim")
    trim: float = param(0.0, unit="s", ge=0, doc="seconds dropped at each end")
    decimation: Literal["fir", "fft"] = "fir"


def _joint_and_reflex(value: Any, where: str, key: str) -> tuple[Any, Any]:
    """The joint model ``{model: ..., ...}`` and the reflex pathway its ``reflex`` key may hold (any joint
    model takes one; ``{pathway: stretch, ...}``, stretch by default), or None; the errors of both at once."""
    has_reflex = isinstance(value, Mapping) and "reflex" in value
    joint = {k: v for k, v in value.items() if k != "reflex"} if has_reflex else value
    problems, out = Problems(), [None, None]
    with problems.catch():
        out[0] = parse_tagged(joint, "model", JOINTS, "joint model", f"{where}: {key}")
    if has_reflex:
        with problems.catch():
            out[1] = parse_tagged(value["reflex"], "pathway", REFLEXES, "reflex pathway", f"{where}: {key}: reflex",
                                  default="stretch")
    problems.raise_all()
    return out[0], out[1]


@dataclasses.dataclass(frozen=True, kw_only=True)
class ExperimentSpec:
    """The experiment block of a study config, as written (:meth:`Experiment.from_mapping`)."""

    joint: tuple = param(parser=_joint_and_reflex, doc="joint model {model: ..., reflex: {...}}")
    apparatus: Any = param(default_factory=PositionServo,
                           parser=tagged("kind", APPARATUS_KINDS, "apparatus", default="position_servo"),
                           doc="{kind: position_servo | torque_drive | handle, ...}")
    perturbation: Any = param(parser=tagged("kind", PERTURBATIONS, "perturbation"), doc="{kind: ..., ...}")
    voluntary: Voluntary = param(default_factory=Voluntary, doc="voluntary torque")
    sensors: Sensors = param(default_factory=Sensors, doc="sensor models {angle: ..., torque: ...}")
    fs_sim: float = param(unit="Hz", gt=0, doc="simulation rate")
    duration: float = param(unit="s", gt=0, doc="simulated record length")
    acquisition: Acquisition = param(default_factory=Acquisition, doc="detrend, decimation, trim")
    gravity: Gravity | None = param(None, doc="gravity on the limb segment")


@dataclasses.dataclass(frozen=True)
class Experiment:
    """A simulated identification experiment (pure description; see :func:`simulate`).

    Parameters
    ----------
    joint : object
        Joint model from :data:`sims.JOINTS`, e.g. :class:`sims.joint_second_order.SecondOrderJoint`.
    perturbation : object
        Perturbation from :data:`sims.PERTURBATIONS` (``generate(n, fs, rng)``), e.g.
        :class:`sims.perturbation_filtered_noise.FilteredNoise`: the position command theta_r of a
        position servo, or the applied torque of a torque drive.
    fs_sim : float
        Simulation rate (Hz), e.g. 5000.
    duration : float
        Simulated record length (s) before trimming.
    apparatus : PositionServo or TorqueDrive
        Default: a position servo of 30 000 N·m/rad.
    voluntary : Voluntary
        Voluntary torque; default zero.
    sensors : Sensors
        Sensor models of the angle and torque channels; default ideal.
    acquisition : Acquisition
        Detrend, decimation and trim; default: detrend, no decimation, no trim.
    gravity : Gravity or None
        Gravity on the limb segment (:mod:`sims.gravity`); default none. Physics backends only.
    reflex : object or None
        A reflex pathway of :data:`sims.REFLEXES` (the ``reflex`` key of the joint's mapping, e.g.
        :class:`sims.reflex_stretch.StretchReflex`); default none. Its torque adds to the joint's.
    backend : str
        The simulation backend (:data:`sims.BACKENDS`), default ``"analytic"``; set by the study part.
    where : str
        Where the description came from, prefixed to error messages (not compared).

    References
    ----------
    Westwick & Perreault 2012, Fig. 1, eqs. 3-8 and Sec. IV.
    """

    joint: Any
    perturbation: Any
    fs_sim: float
    duration: float
    apparatus: Apparatus = dataclasses.field(default_factory=PositionServo)
    voluntary: Voluntary = dataclasses.field(default_factory=Voluntary)
    sensors: Sensors = dataclasses.field(default_factory=Sensors)
    acquisition: Acquisition = dataclasses.field(default_factory=Acquisition)
    gravity: Gravity | None = None
    backend: str = "analytic"
    where: str = dataclasses.field(default="experiment", compare=False, repr=False)
    reflex: Any = None

    def __post_init__(self):
        self._validate()

    @classmethod
    def from_mapping(cls, mapping: Mapping[str, Any] | None, where: str = "experiment",
                     backend: str = "analytic") -> "Experiment":
        """Parse the experiment block of a study config strictly.

        Parameters
        ----------
        mapping : mapping
            Keys ``joint`` (``{model: ..., ...}``), ``perturbation`` (``{kind: ..., ...}``), ``fs_sim``,
            ``duration`` (required); ``apparatus`` (``{kind: position_servo|torque_drive, ...}``),
            ``voluntary``, ``sensors`` (``{angle: ..., torque: ...}``), ``acquisition``, ``gravity``
            (optional).
        where : str
            File and section, prefixed to every error message.
        backend : str
            Name of the simulation backend (a study part's ``backend`` key).

        Raises
        ------
        ConfigError
            Unknown or missing key, wrong unit or type, impossible value; the message names ``where``,
            the section and the key.
        """
        spec = parse(ExperimentSpec, mapping, where)
        joint, reflex = spec.joint
        return cls(joint=joint, reflex=reflex, perturbation=spec.perturbation, apparatus=spec.apparatus,
                   voluntary=spec.voluntary, sensors=spec.sensors, acquisition=spec.acquisition, gravity=spec.gravity,
                   fs_sim=spec.fs_sim, duration=spec.duration, backend=backend, where=where)

    # ----------------------------------------------------------------------------------- derived sizes
    @property
    def n_sim(self) -> int:
        """Number of samples simulated: round(duration · fs_sim)."""
        return int(round(self.duration * self.fs_sim))

    @property
    def fs(self) -> float:
        """Acquired sampling rate (Hz)."""
        return float(self.fs_sim if self.acquisition.fs is None else self.acquisition.fs)

    @property
    def decimation(self) -> int:
        """Whole decimation factor fs_sim / fs (FIR decimation only)."""
        return int(round(self.fs_sim / self.fs))

    @property
    def n_acquired(self) -> int:
        """Samples after decimation, before trimming."""
        if self.acquisition.decimation == "fft":
            return int(round(self.duration * self.fs))
        return -(-self.n_sim // self.decimation)

    def acquired_times(self) -> np.ndarray:
        """Times (s, from the start of the simulation) of the acquired, trimmed samples."""
        return (self.trim_samples + np.arange(self.n)) / self.fs

    @property
    def trim_samples(self) -> int:
        """Samples dropped at each end of the acquired record."""
        return int(round(self.acquisition.trim * self.fs))

    @property
    def n(self) -> int:
        """Number of samples in the acquired trial."""
        return self.n_acquired - 2 * self.trim_samples

    def _validate(self) -> None:
        w = self.where
        for key, v, unit in (("fs_sim", self.fs_sim, "Hz"), ("duration", self.duration, "s")):
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not (math.isfinite(v) and v > 0):
                raise ConfigError(f"{w}: key '{key}': must be a finite number > 0 {unit}, got {v!r}")
        for key, obj, need in (("joint", self.joint, "coefficients_at"),
                               ("perturbation", self.perturbation, "generate"),
                               ("apparatus", self.apparatus, "coupling")):
            if not hasattr(obj, need):
                raise ConfigError(f"{w}: key '{key}': expected a {key} model, got {obj!r}")
        if self.n_sim < 2:
            raise ConfigError(f"{w}: key 'duration': {self.duration:g} s at fs_sim = {self.fs_sim:g} Hz gives "
                              f"{self.n_sim} sample(s); need at least 2")
        fs = self.fs
        if fs > self.fs_sim * (1 + 1e-12):
            raise ConfigError(f"{w}: acquisition: key 'fs': {fs:g} Hz is above fs_sim = {self.fs_sim:g} Hz; "
                              f"acquisition can only decimate")
        q = self.fs_sim / fs
        if self.acquisition.decimation == "fft":
            m = self.duration * fs
            if abs(m - round(m)) > 1e-9 * m:
                raise Incompatible(f"{w}: acquisition: key 'fs': fft decimation needs a whole number of samples "
                                  f"in {self.duration:g} s; {fs:g} Hz gives {m:.6g}")
        elif abs(q - round(q)) > 1e-9 * q:
            lo, hi = self.fs_sim / math.ceil(q), self.fs_sim / math.floor(q)
            raise Incompatible(f"{w}: acquisition: key 'fs': {fs:g} Hz does not divide fs_sim = {self.fs_sim:g} Hz "
                              f"(decimation factor {q:.6g} is not a whole number); e.g. {lo:g} or {hi:g} Hz")
        if self.n < 2:
            n_acq = self.n_acquired
            raise ConfigError(f"{w}: acquisition: key 'trim': dropping {self.acquisition.trim:g} s at both ends "
                              f"leaves {max(self.n, 0)} of {n_acq} samples ({self.duration:g} s at {fs:g} Hz); "
                              f"need at least 2")
        contact = getattr(self.joint, "contact", None)
        if contact is not None and not getattr(self.apparatus, "angle_is_drive", False):
            raise Incompatible(f"{w}: key 'apparatus': joint model '{self.joint.model}' has a hand contact and "
                              f"needs apparatus kind 'handle', got '{self.apparatus.kind}'")
        try:
            self.apparatus.coupling(self.joint)
        except ConfigError as exc:
            raise type(exc)(f"{w}: key 'apparatus': {exc}") from None
        self.perturbation.check(self.fs_sim, self.duration, f"{w}: perturbation")
        self.voluntary.check(self.fs_sim, f"{w}: voluntary")
        self.sensors.check(self.fs_sim, f"{w}: sensors")
        if self.gravity is not None:
            self.gravity.check(float(np.min(self.joint.coefficients_at(np.zeros(1))[0])), w)
        if self.reflex is not None:
            self.reflex.check(self.fs_sim, self.duration, f"{w}: joint: reflex")
        if not isinstance(self.backend, str) or self.backend not in BACKENDS:
            raise ConfigError(f"{w}: key 'backend': unknown simulation backend {self.backend!r}; "
                              f"known: {', '.join(BACKENDS.names())}")
        try:
            BACKENDS.get(self.backend)().check(self)
        except ConfigError as exc:
            raise type(exc)(f"{w}: {exc}") from None

    # ------------------------------------------------------------------------------------- acquisition
    def acquire(self, x: np.ndarray) -> np.ndarray:
        """Apply the acquisition steps to signals at the simulation rate: detrend, decimate, trim.

        ``x`` is one signal, or several as the columns of a 2-D array (all steps act along axis 0).
        """
        x = np.asarray(x, float)
        if self.acquisition.detrend:
            x = detrend_linear(x)
        if self.acquisition.decimation == "fft":
            x = decimate_fft(x, self.n_acquired)
        else:
            x = decimate(x, self.decimation)
        i = self.trim_samples
        return x[i:len(x) - i]


def simulate(experiment: Experiment, seed: int | np.random.SeedSequence, backend: str | Any | None = None, *,
             name: str = "trial", replicate: int = 0, realization: int = 0) -> Trial:
    """Simulate one trial of ``experiment``.

    Steps: perturbation and voluntary torque at fs_sim -> backend (limb + apparatus) -> sensor models
    (filter, noise, quantization) -> acquisition (detrend, decimate, trim).

    Parameters
    ----------
    experiment : Experiment
        The description.
    seed : int or numpy.random.SeedSequence
        All randomness comes from ``SeedSequence(seed).spawn(4)``, one independent stream per source in
        the order of :data:`STREAMS` (perturbation, voluntary torque, angle noise, torque noise): changing
        one source's level changes no other source. Same experiment and seed -> bit-identical arrays.
    backend : str or object, optional
        Name in :data:`sims.BACKENDS` or a :class:`sims.backend.Backend`; default: the experiment's own
        (``experiment.backend``, ``"analytic"`` unless a study part says otherwise).
    name : str
        Name of the trial.
    replicate : int
        0 for the trial itself; 1, 2, ... for further trials with the same perturbation and voluntary
        torque but new sensor-noise realisations (e.g. the validation trial of van de Ruit et al. 2018).
    realization : int
        0 for the trial itself; 1, 2, ... for further realizations of the same experiment: every random
        stream (perturbation, voluntary torque, noise) drawn anew, the joint's time variation unchanged
        (an ensemble, MacNeil et al. 1992; a jittered time variation is the caller's, e.g.
        :mod:`sims.subjects`). Combines with ``replicate`` (new noise for that realization).

    Returns
    -------
    Trial
        ``time`` from 0 at the first kept sample, measured ``angle`` and ``torque`` at
        ``experiment.fs``, ``imposed`` = 'angle' (position servo, handle) or 'torque' (torque drive), and
        ``truth`` = Truth(I, B, K, signals, num, den): I, B, K are numbers, or arrays at the trial's
        samples when the joint varies in time; ``num``/``den`` the frozen transfer function from the
        trial's input to its output; the signals all went through the same acquisition as the
        measurements and align with them sample by sample:

        - ``"angle"``: the measured angle through the angle sensor's filter (if any), without noise or
          quantization;
        - ``"torque"``: the impedance torque I theta'' + B theta' + K theta through the torque sensor's
          filter, without noise. For a position servo or handle this is the measured torque without the
          voluntary torque and without sensor noise (eq. 8: T_m = T_imp - T_v);
        - ``"command"``: the perturbation signal (position command, or applied torque);
        - ``"voluntary"``: the voluntary torque T_v through the torque sensor's filter;
        - ``"movement"`` (with a voluntary movement): the intended trajectory theta_n;
        - whatever else the backend knows (:attr:`sims.backend.Response.extra`), e.g. ``"gravity_torque"``
          and ``"gravity_stiffness"`` from a physics backend with gravity.

    References
    ----------
    Westwick & Perreault 2012, Fig. 1, eqs. 3-8 and Sec. IV; Xu & Hollerbach 1998, eq. 7; van de Ruit
    et al. 2018, eqs. 11-13.
    """
    exp, runner = _resolved(experiment, seed, backend, replicate, realization)
    rng = streams(seed, replicate, realization)
    t_start = time.perf_counter()
    by_name = backend is None or isinstance(backend, str)    # a backend object has no name to key on
    key = _reuse.response_key(exp, seed, realization, exp.backend) if by_name else None

    def acquire() -> tuple[Trial, bool]:   # on the response, simulated or reused (sims.reuse)
        (drive, tv, resp), reused = _reuse.lookup(key, lambda: _respond(exp, runner, rng))
        return _measured(exp, drive, tv, resp, rng, key, replicate, name), reused

    (trial, reused), whole = _reuse.lookup_trial(_reuse.trial_key(key, exp, replicate, name), acquire)
    _backend.record(getattr(runner, "name", "") or type(runner).__name__, time.perf_counter() - t_start,
                     reused or whole)
    return trial


def limb_response(experiment: Experiment, seed: int | np.random.SeedSequence,
                  realization: int = 0) -> tuple[Response, np.ndarray]:
    """``(response, voluntary torque)`` of realization ``realization``: the limb's response at the simulation
    rate as the backend computed it (:class:`sims.backend.Response`: angle, velocity and acceleration from the
    dynamics, the measured and the impedance torque), before sensors, noise and acquisition; the one
    :func:`simulate` acquires (the same random streams; inside a :class:`sims.reuse.reuse_responses` block
    computed once for both). For code that needs the exact signals, e.g. the oracle of a comparison grid
    (``benchmarks/compare/oracle.py``), which sees the truth by design."""
    exp, runner = _resolved(experiment, seed, None, 0, realization)
    key = _reuse.response_key(exp, seed, realization, exp.backend)
    (_drive, tv, resp), _ = _reuse.lookup(key, lambda: _respond(exp, runner, streams(seed, 0, realization)))
    return resp, tv


def _resolved(exp: Experiment, seed: Any, backend: str | Any | None, replicate: int,
              realization: int) -> tuple[Experiment, Any]:
    """The experiment to simulate (on ``backend`` when it is given and not the experiment's, checked there)
    and the backend that runs it; the arguments of :func:`simulate` checked."""
    if not isinstance(exp, Experiment):
        raise TypeError(f"simulate() needs an Experiment, got {type(exp).__name__}")
    if seed is None:
        raise TypeError("simulate() needs a seed (an int >= 0 or a SeedSequence); None is not reproducible")
    for key, v in (("replicate", replicate), ("realization", realization)):
        if isinstance(v, bool) or not isinstance(v, int) or v < 0:
            raise ValueError(f"simulate(): {key} must be a whole number >= 0, got {v!r}")
    if backend is not None and backend != exp.backend:
        if isinstance(backend, str):
            exp = dataclasses.replace(exp, backend=backend)   # validates: check() of that backend
        else:
            backend.check(exp)
    return exp, _backend.resolve(exp.backend if backend is None else backend)


def _respond(exp: Experiment, runner: Any, rng: Mapping[str, np.random.Generator]) -> tuple:
    """The half of a trial that sensors, noise and acquisition do not change: the drive, the voluntary
    torque (with what holds an intended movement, and the trajectory, against the limb and gravity) and
    the backend's response."""
    fs, n = exp.fs_sim, exp.n_sim
    drive = exp.perturbation.generate(n, fs, rng["perturbation"])
    tv = exp.voluntary.generate(n, fs, rng["voluntary"])
    x0 = (0.0, 0.0)
    if exp.voluntary.moving:
        t = np.arange(n) / fs
        pos, vel, acc = exp.voluntary.movement(t)
        I, B, K = exp.joint.coefficients_at(t)
        c = exp.apparatus.coupling(exp.joint)
        tv = tv + I * acc + (B + c.b_a) * vel + (K + c.k_a) * pos
        x0 = (float(pos[0]), float(vel[0]))
    if exp.gravity is not None:   # the subject holds the intended trajectory against gravity
        tv = tv - exp.gravity.torque(exp.voluntary.position(np.arange(n) / fs))
    return drive, tv, runner.respond(exp, drive, tv, x0)


def _active(exp: Experiment) -> bool:
    """Whether the truth's torque and voluntary torque are apart (a voluntary torque or gravity)."""
    return exp.voluntary.active or exp.gravity is not None


def _sensed(exp: Experiment, drive: np.ndarray, tv: np.ndarray, resp: Response) -> dict[str, np.ndarray]:
    """The noise-free channels: the sensors' filters, then the acquisition."""
    fs, n = exp.fs_sim, exp.n_sim
    if resp.angle_measured is not None:
        angle_true = resp.angle_measured
    else:
        angle_true = drive if exp.apparatus.angle_is_drive else resp.angle
    angle_filtered = exp.sensors.angle.filtered(angle_true, fs)
    # one pass of the torque sensor's filter over the measured, impedance and voluntary torques
    torques = exp.sensors.torque.filtered(np.column_stack([resp.torque_measured, resp.torque_impedance,
                                                           tv, *resp.torque_parts.values()]), fs)
    out = {"angle_filtered": angle_filtered, "torque_filtered": torques[:, 0],
           "parts_filtered": torques[:, 3:],
           "angle": exp.acquire(angle_filtered), "torque": exp.acquire(torques[:, 0]),
           "truth_torques": exp.acquire(torques[:, 1:3] if _active(exp) else torques[:, 1]),
           "command": exp.acquire(drive)}
    if exp.voluntary.moving:
        out["movement"] = exp.acquire(exp.voluntary.position(np.arange(n) / fs))
    if resp.extra:
        out["extra"] = exp.acquire(np.column_stack([resp.extra[k] for k in resp.extra]))
    return out


def _noise(exp: Experiment, sensor: Sensor, stream: str, rng: Mapping[str, np.random.Generator], key: Any,
           replicate: int) -> Callable[[], tuple[np.ndarray, np.ndarray]]:
    """The unit noise of a channel, drawn once for every noise level of this seed, replicate and
    realization (:mod:`sims.reuse`)."""
    def draw():
        return unit_noise(sensor, exp.n_sim, rng[stream], exp.acquire, exp.fs_sim)
    return lambda: _reuse.lookup_noise(_reuse.noise_key(key, exp, stream, sensor.noise_filter, replicate), draw)[0]


def _measured(exp: Experiment, drive: np.ndarray, tv: np.ndarray, resp: Response,
              rng: Mapping[str, np.random.Generator], key: Any, replicate: int, name: str) -> Trial:
    """The trial of a response: sensors, noise, acquisition and the truth."""
    sensed, _ = _reuse.lookup_sensed(_reuse.sensed_key(key, exp), lambda: _sensed(exp, drive, tv, resp))
    angle, angle_clean = measure(exp.sensors.angle, sensed["angle_filtered"], sensed["angle"],
                                  _noise(exp, exp.sensors.angle, "angle_noise", rng, key, replicate), exp.acquire)
    torque, _ = measure(exp.sensors.torque, sensed["torque_filtered"], sensed["torque"],
                         _noise(exp, exp.sensors.torque, "torque_noise", rng, key, replicate), exp.acquire)
    truth_torques = sensed["truth_torques"]
    active = _active(exp)
    signals = {
        "angle": angle_clean,
        "torque": np.ascontiguousarray(truth_torques[:, 0]) if active else truth_torques,
        "command": sensed["command"],
        "voluntary": np.ascontiguousarray(truth_torques[:, 1]) if active else np.zeros(len(angle)),
    }
    if exp.voluntary.moving:
        signals["movement"] = sensed["movement"]
    if resp.extra:
        acquired = sensed["extra"]
        signals.update({k: np.ascontiguousarray(acquired[:, i]) for i, k in enumerate(resp.extra)})
    signals.update(_truth.part_signals(exp, list(resp.torque_parts), sensed["parts_filtered"]))   # reflex, scheduling
    return Trial.from_arrays(angle, torque, exp.fs, imposed=exp.apparatus.imposed,
                             truth=_truth.truth(exp, signals, resp.angle), name=name)
