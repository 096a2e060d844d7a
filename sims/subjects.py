"""Simulated subjects of a time-varying torque task: the design of van de Ruit et al. (2018), Table II.

The paper's Table II comes from six people who each made six 50 s trials while tracking a sinusoidal
flexion torque (5-20 % of their maximum voluntary torque, MVT, at 0.05 Hz) against a multisine
perturbation of the handle. There are no recordings here, so the design is simulated:

* a subject is the wrist-with-contact model with its parameters drawn around the model's (lognormal,
  coefficient of variation ``parameter_cv``), an MVT, and a torque-noise level;
* a trial is one attempt at the task: the voluntary torque ``tau_v(t) = MVT (mid + half a sin(2 pi f
  (t - shift)) + drift (t / T - 1/2))`` with a trial's own time ``shift`` (timing), relative
  amplitude ``a`` and linear ``drift`` of the mean (fractions of MVT); the intrinsic stiffness follows
  the torque, ``k(t) = k_mean + k_swing (tau_v / MVT - mid) / half``, so the nominal trial swings
  between ``k_mean -+ k_swing``;
* the voluntary torque is added to the measured torque (the task's torque is measured with the
  perturbation's response); the torque sensor adds filtered noise at the subject's level.

Every draw is seeded: the subjects from ``SubjectDesign.seed`` (the same six people in every case), the
trials from the case seed and the subject.

References
----------
van de Ruit, M. et al. (2018). Revealing time-varying joint impedance with kernel-based regression and
nonparametric decomposition. IEEE Trans. Control Syst. Technol. 28(1), 224-237. Sec. V-A...F, Table II.
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np

from jointbench.core.errors import ConfigError
from jointbench.core.schema import param
from jointbench.core.types import Trial
from jointbench.sims.experiment import Experiment, simulate
from jointbench.sims.profile import Piecewise


@dataclasses.dataclass(frozen=True)
class SubjectDesign:
    """How the simulated subjects and their trials are drawn (all fractions of MVT are 0 ... 1)."""

    count: int = param(6, ge=1, doc="number of subjects")
    trials: int = param(6, ge=2, doc="trials per subject")
    seed: int = param(2018, ge=0, doc="draws the subjects' parameters (the same people for every case seed)")
    parameter_cv: float = param(0.2, ge=0, lt=1, doc="spread of I, b, k_mean, k_swing, b_c, k_c across "
                                                     "subjects (lognormal, coefficient of variation)")
    mvt: float = param(8.0, unit="N.m", gt=0, doc="mean maximum voluntary torque")
    mvt_cv: float = param(0.25, ge=0, lt=1, doc="its spread across subjects")
    torque_low: float = param(0.05, ge=0, lt=1, doc="task: lowest target torque (fraction of MVT)")
    torque_high: float = param(0.20, gt=0, le=1, doc="task: highest target torque (fraction of MVT)")
    task_frequency: float = param(0.05, unit="Hz", gt=0, doc="task: frequency of the sinusoidal target")
    task_phase: float = param(0.0, unit="rad", doc="task: phase of the target at t = 0 (simulation time)")
    timing_sd: float = param(1.0, unit="s", ge=0, doc="trial-to-trial SD of the time shift of the torque")
    amplitude_sd: float = param(0.15, ge=0, lt=1, doc="trial-to-trial SD of the relative torque amplitude")
    drift_sd: float = param(0.02, ge=0, lt=1, doc="trial-to-trial SD of the linear drift of the mean torque "
                                                   "over the trial (fraction of MVT, end minus start)")
    noise_variance_ratio: tuple[float, ...] = param((0.1,), doc="torque noise: var(noise) / var(torque) "
                                                                "over the acquired record, per subject "
                                                                "(one value: every subject)")
    knot_step: float = param(0.01, unit="s", gt=0, doc="grid of the piecewise-linear k(t) given to the simulator")

    def __post_init__(self):
        if not self.torque_low < self.torque_high:
            raise ConfigError(f"torque_low = {self.torque_low:g} must be below torque_high = {self.torque_high:g}")
        if len(self.noise_variance_ratio) not in (1, self.count):
            raise ConfigError(f"noise_variance_ratio: one value or one per subject ({self.count}), got "
                              f"{len(self.noise_variance_ratio)}")
        if any(not (math.isfinite(r) and r >= 0) for r in self.noise_variance_ratio):
            raise ConfigError(f"noise_variance_ratio: values must be >= 0, got {list(self.noise_variance_ratio)}")

    @property
    def mid(self) -> float:
        return 0.5 * (self.torque_low + self.torque_high)

    @property
    def half(self) -> float:
        return 0.5 * (self.torque_high - self.torque_low)


@dataclasses.dataclass(frozen=True)
class Subject:
    """One simulated person: wrist parameters, MVT and torque-noise level."""

    index: int
    I: float
    b: float
    k_mean: float
    k_swing: float
    b_c: float
    k_c: float
    mvt: float
    noise_variance_ratio: float

    @property
    def label(self) -> str:
        return f"P{self.index}"


@dataclasses.dataclass(frozen=True)
class TrialPlan:
    """One attempt at the task: the trial's timing, amplitude and drift."""

    subject: Subject
    trial: int
    shift: float
    amplitude: float
    drift: float

    @property
    def label(self) -> str:
        return f"{self.subject.label}-T{self.trial}"


def draw_subjects(design: SubjectDesign, joint) -> list[Subject]:
    """The ``design.count`` subjects around ``joint`` (a ``wrist_contact`` model with a periodic ``k``)."""
    k = joint.k
    k_mean = float(getattr(k, "mean", getattr(k, "value", None)))
    k_swing = float(abs(getattr(k, "amplitude", 0.0)))
    rng = np.random.default_rng(np.random.SeedSequence([design.seed, 0x5B1EC7]))
    out = []
    for i in range(design.count):
        z = rng.standard_normal(7)
        f = np.exp(design.parameter_cv * z[:6])
        ratio = design.noise_variance_ratio[i if len(design.noise_variance_ratio) > 1 else 0]
        out.append(Subject(index=i + 1, I=joint.I * f[0], b=joint.b * f[1], k_mean=k_mean * f[2],
                           k_swing=k_swing * f[3], b_c=joint.b_c * f[4], k_c=joint.k_c * f[5],
                           mvt=design.mvt * float(np.exp(design.mvt_cv * z[6])), noise_variance_ratio=float(ratio)))
    return out


def draw_trials(design: SubjectDesign, subject: Subject, seed: int) -> list[TrialPlan]:
    """The subject's ``design.trials`` trials for case ``seed``."""
    rng = np.random.default_rng(np.random.SeedSequence([seed, subject.index, 0x7A1]))
    z = rng.standard_normal((design.trials, 3))
    return [TrialPlan(subject=subject, trial=j + 1, shift=design.timing_sd * z[j, 0],
                      amplitude=1.0 + design.amplitude_sd * z[j, 1], drift=design.drift_sd * z[j, 2])
            for j in range(design.trials)]


def torque_fraction(design: SubjectDesign, plan: TrialPlan, t: np.ndarray, duration: float) -> np.ndarray:
    """The voluntary torque as a fraction of MVT at simulation times ``t`` (s)."""
    t = np.asarray(t, float)
    w = 2 * np.pi * design.task_frequency
    return (design.mid + design.half * plan.amplitude * np.sin(w * (t - plan.shift) + design.task_phase)
            + plan.drift * (t / duration - 0.5))


def stiffness(design: SubjectDesign, plan: TrialPlan, t: np.ndarray, duration: float) -> np.ndarray:
    """The intrinsic stiffness k(t) (N·m/rad) that follows the trial's torque."""
    s = plan.subject
    return s.k_mean + s.k_swing * (torque_fraction(design, plan, t, duration) - design.mid) / design.half


def trial_experiment(base: Experiment, design: SubjectDesign, plan: TrialPlan) -> Experiment:
    """``base`` with the subject's wrist, the trial's k(t) and the subject's torque noise."""
    s = plan.subject
    knots = np.arange(0.0, base.duration + design.knot_step / 2, design.knot_step)
    k = Piecewise(times=knots.tolist(), values=stiffness(design, plan, knots, base.duration).tolist(),
                  interpolate="linear")
    if k.minimum <= 0:
        raise ConfigError(f"{plan.label}: the drawn stiffness reaches {k.minimum:.3g} N m/rad; lower amplitude_sd, "
                          f"drift_sd or the model's k swing")
    joint = dataclasses.replace(base.joint, I=s.I, b=s.b, k=k, b_c=s.b_c, k_c=s.k_c)
    torque = dataclasses.replace(base.sensors.torque, noise_rms=None, noise_snr_db=None,
                                 noise_variance_ratio=s.noise_variance_ratio or None)
    return dataclasses.replace(base, joint=joint, sensors=dataclasses.replace(base.sensors, torque=torque))


def simulate_trial(base: Experiment, design: SubjectDesign, plan: TrialPlan, seed: int,
                   same_input: bool) -> Trial:
    """Simulate one trial: the wrist under the perturbation, noise, and the voluntary torque added.

    Parameters
    ----------
    same_input : bool
        True: every trial of the subject has the same perturbation (the paper's multisine design;
        trials differ by ``replicate``: noise only); False: each trial is a new ``realization`` of
        the perturbation (e.g. PRALDS for the ensemble methods).

    Returns
    -------
    Trial
        Named ``P<subject>-T<trial>``; ``truth.signals['voluntary']`` holds the added voluntary torque
        and ``truth.K`` the intrinsic k(t).
    """
    exp = trial_experiment(base, design, plan)
    ss = np.random.SeedSequence([seed, plan.subject.index])
    j = plan.trial - 1
    trial = simulate(exp, ss, name=plan.label, replicate=j if same_input else 0, realization=0 if same_input else j)
    tv = plan.subject.mvt * torque_fraction(design, plan, exp.acquired_times(), exp.duration)
    truth = dataclasses.replace(trial.truth, signals={**trial.truth.signals, "voluntary": tv})
    return trial.replace(torque=trial.torque + tv, truth=truth)
