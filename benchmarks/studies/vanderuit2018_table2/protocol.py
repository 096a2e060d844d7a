"""Protocol of van de Ruit et al. (2018), experimental comparison (Sec. V-D...F, Table II), on simulated subjects.

One case = one simulated subject at one seed: the subject's trials are simulated
(:mod:`sims.subjects`), the voluntary torque is removed by the paper's low-frequency fit, and

* single trial (Table II, left): each listed estimator is fitted on every trial and validated on the
  trial itself (VAF_self) and on each other trial (VAF_val);
* ensemble (Table II, right): with each trial left out in turn, every estimator is fitted on the
  ensemble of the others and validated on the left-out trial (KBR and skirt on the ensemble average at
  the low rate, the IRF methods on the realizations at the acquired rate);
* what only simulation gives: the stiffness-tracking RMSE and bias of every fit against the true
  frozen stiffness (of the trial, or the mean over the ensemble's trials).

VAFs are computed after removing the frequencies below ``highpass`` (0.8 Hz) from the measured and the
predicted torque, on the scored interval.

References
----------
van de Ruit, M., Cavallo, G., Lataire, J., van der Helm, F. C. T., Mugge, W., van Wingerden, J. W. &
Schouten, A. C. (2018). Revealing time-varying joint impedance with kernel-based regression and
nonparametric decomposition. IEEE Trans. Control Syst. Technol. 28(1), 224-237,
doi:10.1109/TCST.2018.2881664. Sec. V-D (low-frequency fit, 0.8 Hz), V-E (comparison, 100 Hz), Table II.
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np

from jointbench.core.scores import vaf
from jointbench.benchmarks.protocols import Context, register
from jointbench.benchmarks.scoring import fit_gated, frozen_stiffness
from jointbench.core.ensemble import Ensemble, valid_mask
from jointbench.core.errors import InputError, Refused
from jointbench.core.estimate_tv import TVIRFEstimate
from jointbench.core.schema import param, parse
from jointbench.core.signal import decimate_fft
from jointbench.core.types import Trial
from jointbench.sims.subjects import SubjectDesign, draw_subjects, draw_trials, simulate_trial

MODES = ("single", "ensemble")


# ----------------------------------------------------------------------------------- pure helpers
def low_frequency_basis(n: int, fs: float) -> np.ndarray:
    """Columns 1, t, cos(w t), sin(w t), cos(2 w t), sin(2 w t) with ``w = 2 pi / T``, ``T = n / fs``.

    References
    ----------
    van de Ruit et al. (2018), Sec. V-D: "a constant, a linear function and four goniometric functions
    [cos(wt), sin(wt), cos(2wt), sin(2wt)], where w is the lowest frequency fitting the analyzed time
    window (T), i.e., 1/T".
    """
    t = np.arange(n) / fs
    w = 2 * np.pi / (n / fs)
    return np.column_stack([np.ones(n), t - t.mean(), np.cos(w * t), np.sin(w * t), np.cos(2 * w * t),
                            np.sin(2 * w * t)])


def remove_low_frequency(y: np.ndarray, fs: float) -> np.ndarray:
    """``y`` minus its least-squares fit on :func:`low_frequency_basis` (the voluntary torque removal)."""
    B = low_frequency_basis(len(y), fs)
    return y - B @ np.linalg.lstsq(B, y, rcond=None)[0]


def band(x: np.ndarray, fs: float, low: float, high: float | None = None) -> np.ndarray:
    """``x`` with the DFT bins below ``low`` (and from ``high`` up) zeroed, over the whole record."""
    X = np.fft.rfft(x)
    f = np.fft.rfftfreq(len(x), 1.0 / fs)
    X[f < low] = 0.0
    if high is not None:
        X[f >= high] = 0.0
    return np.fft.irfft(X, len(x))


def to_rate(trial: Trial, fs: float) -> Trial:
    """The trial decimated in the frequency domain to ``fs`` (same duration; the truth is dropped)."""
    m = int(round(trial.n * fs / trial.fs))
    if m == trial.n:
        return trial
    return Trial.from_arrays(decimate_fft(trial.angle, m), decimate_fft(trial.torque, m), trial.fs * m / trial.n,
                             t0=trial.time[0], imposed=trial.imposed, name=trial.name)


def true_stiffness(trial: Trial, line_hz: float | None) -> dict[str, np.ndarray]:
    """The trial's true frozen stiffness at its samples: ``static`` (the gain at 0 Hz, what an IRF's sum
    estimates) and ``line`` (``|H(j 2 pi f_1, t)|`` at the lowest excited line, the paper's stiffness of
    KBR and skirt; the static gain when there is no line)."""
    static = frozen_stiffness(trial)
    line = static if line_hz is None else frozen_stiffness(trial, line_hz)
    return {"static": static, "line": line, "k": trial.truth.at("K", trial.time, trial.time)}


def mean_sd(values) -> tuple[float, float]:
    v = np.asarray(values, float)
    v = v[np.isfinite(v)]
    return (float(np.mean(v)), float(np.std(v, ddof=1)) if len(v) > 1 else 0.0) if len(v) else (math.nan, math.nan)


# ---------------------------------------------------------------------------------------- protocol
@dataclasses.dataclass(frozen=True)
class Table2Params:
    """One simulated subject of Table II; ``subject`` normally comes from the part's sweep."""

    subject: int = param(ge=1, doc="subject number (1 ... subjects.count)")
    subjects: dict = param(default_factory=dict, doc="the simulated subjects (sims.subjects.SubjectDesign)")
    same_input: bool = param(True, doc="the same perturbation in every trial (the paper's multisine design); "
                                       "false: a new realization of it per trial")
    low_rate: float = param(44.0, unit="Hz", gt=0, doc="rate of the estimators in low_rate_estimators")
    low_rate_estimators: tuple[str, ...] = param(("kbr", "skirt"), doc="fitted at low_rate (frequency-domain "
                                                                       "decimation of the window)")
    single_trial: tuple[str, ...] = param(("kbr", "skirt"), doc="estimators of the single-trial columns")
    voluntary_fit: bool = param(True, doc="remove the low-frequency fit (Sec. V-D) from every torque")
    highpass: float = param(0.8, unit="Hz", ge=0, doc="frequencies below are removed before every VAF")
    common_band: float = param(22.0, unit="Hz", gt=0, doc="upper edge of the band of the vaf_*_common metrics")
    score: tuple[float, ...] = param((5.0, 35.0), unit="s", doc="scored interval (s of the analysis window)")
    curve_subjects: tuple[int, ...] = param((1,), doc="subjects whose stiffness curves are recorded")
    curve_seeds: tuple[int, ...] = param((0,), doc="... at these seeds")
    curve_step: float = param(0.1, unit="s", gt=0, doc="time grid of the recorded stiffness curves")

    def __post_init__(self):
        design = self.design
        if self.subject > design.count:
            raise ValueError(f"subject {self.subject} is not among the {design.count} subjects")
        if len(self.score) != 2 or not self.score[0] < self.score[1]:
            raise ValueError(f"score must be (start, end) with start < end, got {self.score}")

    @property
    def design(self) -> SubjectDesign:
        return parse(SubjectDesign, self.subjects, "params: subjects")


def _skip_reason(name: str, estimator, data, multisine: bool) -> str | None:
    why = estimator.refuses(data)
    if why:
        return why
    tags = estimator_tags(name)
    if "multisine" in tags and not multisine:
        return f"{name}: needs a sparse multisine input (tag 'multisine'); this part's perturbation is not one"
    return None


def estimator_tags(name: str) -> frozenset:
    from jointbench import estimators

    return estimators.REGISTRY.tags(name) if name in estimators.REGISTRY else frozenset()


class _Case:
    """The simulated trials of one subject at one seed, at both rates, with their scoring pieces."""

    def __init__(self, ctx: Context, p: Table2Params):
        exp = ctx.experiment
        design = p.design
        subject = draw_subjects(design, exp.joint)[p.subject - 1]
        plans = draw_trials(design, subject, ctx.seed)
        raw = [simulate_trial(exp, design, plan, ctx.seed, p.same_input) for plan in plans]
        self.subject, self.plans, self.p, self.raw = subject, plans, p, raw
        self.multisine = getattr(exp.perturbation, "kind", "") == "multisine"
        self.line_hz = float(exp.perturbation.lines[0]) if self.multisine else None
        self.trials = [t.replace(torque=remove_low_frequency(t.torque, t.fs)) if p.voluntary_fit else t for t in raw]
        self.low = [to_rate(t, p.low_rate) for t in self.trials]
        self.truth = [true_stiffness(t, self.line_hz) for t in raw]
        self.time = self.trials[0].time
        self.scored = (self.time >= p.score[0] - 1e-9) & (self.time <= p.score[1] + 1e-9)
        self.measured = {}     # (rate, trial, upper band edge) -> band-limited measured torque
        self.predictions = {}  # (estimate, input) -> its prediction and its band-limited versions

    def data(self, name: str, idx: list[int]):
        """The trials ``idx`` at the estimator's rate: one trial, or an ensemble of several."""
        src = self.low if name in self.p.low_rate_estimators else self.trials
        if len(idx) == 1:
            return src[idx[0]]
        return Ensemble(tuple(src[i] for i in idx), name=f"{self.subject.label} trials "
                                                         f"{','.join(str(i + 1) for i in idx)}")

    def prediction(self, est, u: np.ndarray, fs: float | None = None, high: float | None = None) -> np.ndarray:
        """``est.predict(u)``, computed once per estimate and input (the trials of a subject share the
        multisine: same_input); with ``fs``, its :func:`band` from ``highpass`` to ``high``, also once."""
        key = (id(est), np.asarray(u, float).tobytes())
        if key not in self.predictions or self.predictions[key][0] is not est:
            self.predictions[key] = (est, np.asarray(est.predict(u), float), {})
        _, yhat, banded = self.predictions[key]
        if fs is None:
            return yhat
        if high not in banded:
            banded[high] = band(yhat, fs, self.p.highpass, high)
        return banded[high]

    def vafs(self, name: str, est, j: int) -> dict[str, float]:
        """VAF (%) of the prediction of trial ``j`` (high-passed, scored interval), and in the common band."""
        low = name in self.p.low_rate_estimators
        tr = (self.low if low else self.trials)[j]
        m = (tr.time >= self.p.score[0] - 1e-9) & (tr.time <= self.p.score[1] + 1e-9)
        out = {}
        for tag, high in (("", None), ("_common", self.p.common_band)):
            if (low, j, high) not in self.measured:
                self.measured[(low, j, high)] = band(tr.output, tr.fs, self.p.highpass, high)
            y = self.measured[(low, j, high)]
            out[tag] = vaf(y[m], self.prediction(est, tr.input, tr.fs, high)[m])
        return out

    def stiffness_errors(self, est, idx: list[int]) -> tuple[dict[str, float], np.ndarray, np.ndarray]:
        """RMSE and bias of the estimated stiffness against the mean true stiffness of trials ``idx``."""
        kind = "static" if isinstance(est, TVIRFEstimate) else "line"
        true = np.mean([self.truth[i][kind] for i in idx], axis=0)
        khat = np.asarray(est.stiffness(self.time), float)
        m = self.scored & valid_mask(est, self.time)
        err = khat[m] - true[m]
        return {"rmse_k": float(np.sqrt(np.mean(err ** 2))), "bias_k": float(np.mean(err)),
                "rmse_k_rel": float(np.sqrt(np.mean(err ** 2)) / np.mean(true[m]))}, khat, true


def _response_share(p: Table2Params) -> dict:
    """What of the parameters decides the simulated responses of a case (its subject and the design without
    the noise levels, which only the sensors see): parts that differ in noise or estimators share them."""
    return {"subject": p.subject, "same_input": p.same_input,
            "subjects": {k: v for k, v in p.subjects.items() if k != "noise_variance_ratio"}}


@register("vanderuit2018.table2", Table2Params, share=_response_share)
def table2(ctx: Context) -> None:
    """Table II for one simulated subject: single-trial and ensemble VAFs, stiffness RMSE and bias.

    Metrics (percent for VAFs, N·m/rad for stiffness), labelled ``mode`` (single, ensemble),
    ``fit_trial`` / ``val_trial`` (1-based):

    * single trial: ``vaf_self`` (fit trial), ``vaf_val`` (each other trial), ``rmse_k``, ``bias_k``,
      ``rmse_k_rel`` (against the fitted trial's true stiffness);
    * ensemble: ``vaf_val`` (left-out trial) and the stiffness errors against the mean true stiffness of
      the ensemble's trials;
    * ``..._common``: the same VAFs restricted to ``highpass ... common_band`` Hz (the band both rates hold);
    * ``skipped`` (value NaN, ``reason``): an estimator that does not take the data (its ``accepts``, or
      a multisine estimator without a multisine);
    * without estimator: ``noise_variance_ratio`` (achieved, per trial) and ``k_true_min``/``k_true_max``.
    """
    p = ctx.params
    case = _Case(ctx, p)
    R = len(case.trials)
    for j, tr in enumerate(case.raw):
        y0 = tr.truth.signals["torque"]
        noise = tr.torque - y0 - tr.truth.signals["voluntary"]
        ctx.metric("noise_variance_ratio", float(np.var(noise) / np.var(y0)), trial=j + 1)
    k_all = np.concatenate([t["k"] for t in case.truth])
    ctx.metric("k_true_min", float(k_all.min()))
    ctx.metric("k_true_max", float(k_all.max()))
    record = p.subject in p.curve_subjects and ctx.seed in p.curve_seeds
    grid = np.arange(case.time[0], case.time[-1] + 1e-9, p.curve_step)

    def curve(values: np.ndarray, **labels) -> None:
        if record:
            ctx.curve("stiffness", grid, np.interp(grid, case.time, values), **labels)

    for name, estimator in ctx.estimators.items():
        # ------------------------------------------------------------------------- single trial
        if name in p.single_trial:
            for j in range(R):
                data = case.data(name, [j])
                why = _skip_reason(name, estimator, data, case.multisine)
                if why:
                    ctx.metric("skipped", math.nan, name, mode="single", reason=why)
                    break
                try:
                    est = fit_gated(estimator, data)
                except Refused as exc:       # the output gate: this fit refused, the others kept
                    ctx.refused(name, exc, mode="single", fit_trial=j + 1)
                    continue
                self_v = case.vafs(name, est, j)
                for tag, v in self_v.items():
                    ctx.metric("vaf_self" + tag, v, name, mode="single", fit_trial=j + 1)
                for k in range(R):
                    if k != j:
                        for tag, v in case.vafs(name, est, k).items():
                            ctx.metric("vaf_val" + tag, v, name, mode="single", fit_trial=j + 1, val_trial=k + 1)
                errs, khat, true = case.stiffness_errors(est, [j])
                for metric, v in errs.items():
                    ctx.metric(metric, v, name, mode="single", fit_trial=j + 1)
                if j == 0:
                    curve(khat, series=name, mode="single", estimator=name)
                    curve(true, series="truth", mode="single", estimator=name)
        # ----------------------------------------------------------------------------- ensemble
        for j in range(R):
            idx = [i for i in range(R) if i != j]
            data = case.data(name, idx)
            why = _skip_reason(name, estimator, data, case.multisine)
            if why:
                ctx.metric("skipped", math.nan, name, mode="ensemble", reason=why)
                break
            try:
                est = fit_gated(estimator, data)
            except Refused as exc:           # the output gate: this fit refused, the others kept
                ctx.refused(name, exc, mode="ensemble", val_trial=j + 1)
                continue
            except InputError as exc:        # the data cannot support this estimator: a reason, not a crash
                ctx.metric("skipped", math.nan, name, mode="ensemble", reason=str(exc))
                break
            for tag, v in case.vafs(name, est, j).items():
                ctx.metric("vaf_val" + tag, v, name, mode="ensemble", val_trial=j + 1)
            errs, khat, true = case.stiffness_errors(est, idx)
            for metric, v in errs.items():
                ctx.metric(metric, v, name, mode="ensemble", val_trial=j + 1)
            if j == R - 1:
                curve(khat, series=name, mode="ensemble", estimator=name)
                curve(true, series="truth", mode="ensemble", estimator=name)
    curve(np.mean([t["k"] for t in case.truth[:-1]], axis=0), series="k", mode="ensemble", estimator="")
