"""Protocol of van de Ruit et al. (2018), simulation study (Sec. IV, Table I, Figs. 3-4, 7(b), 8(a)).

One case = one stiffness variation (sine 20 s, square 10, 20 or 30 s) at one noise level and seed: the
estimation trial and the validation trial (same multisine, other noise realisation) are simulated,
every listed estimator is fitted on the estimation trial, and the metrics of eqs. 17-18 are recorded.

References
----------
van de Ruit, M., Cavallo, G., Lataire, J., van der Helm, F. C. T., Mugge, W., van Wingerden, J. W. &
Schouten, A. C. (2018). Revealing time-varying joint impedance with kernel-based regression and
nonparametric decomposition. IEEE Trans. Control Syst. Technol. 28(1), 224-237,
doi:10.1109/TCST.2018.2881664. Sec. IV-A...F, eqs. 11-18, Table I, Figs. 3, 4, 7(b), 8(a).
"""
from __future__ import annotations

import dataclasses
import math
from typing import Any, Literal

import numpy as np

from jointbench import estimators
from jointbench import sims
from jointbench.benchmarks.metrics import rmse
from jointbench.core.scores import vaf
from jointbench.benchmarks.protocols import Context, register
from jointbench.benchmarks.scoring import basis_bound, fit_gated, frozen_stiffness
from jointbench.estimators.skirt import basis as skirt_basis
from jointbench.core.errors import ConfigError, Refused
from jointbench.core.schema import param
from jointbench.sims.profile import parse_profile

#: metric names of Table I (eqs. 17-18)
TABLE1_METRICS = ("vaf_self", "vaf_optim", "vaf_val", "rmse_k")


# ----------------------------------------------------------------------------------- pure helpers
def scored_mask(time: np.ndarray, window: tuple[float, float]) -> np.ndarray:
    """Samples of the analysis window whose time (s, from the first kept sample) lies in ``window``."""
    lo, hi = window
    return (time >= lo - 1e-9) & (time <= hi + 1e-9)


def noise_ratio(snr_db: float, definition: str, ratios: dict) -> float:
    """var(noise) / var(noise-free torque) for the nominal ``snr_db`` (0 for an infinite SNR).

    ``definition`` 'snr_db': 10^(-snr_db / 10) (the standard definition); 'variance_ratio': the ratio
    given for that nominal level in ``ratios`` (keys: the nominal dB values).
    """
    if not math.isfinite(snr_db):
        return 0.0
    if definition == "snr_db":
        return 10.0 ** (-snr_db / 10.0)
    for k, v in ratios.items():
        if math.isclose(float(k), snr_db):
            return float(v)
    raise ConfigError(f"params: 'variance_ratio' has no entry for snr_db = {snr_db:g} dB; "
                      f"entries: {', '.join(str(k) for k in ratios)}")


def prefilter_noise_ratio(snr_db: float, cutoff_hz: float, order: int, white_hz: float, scored_hz: float) -> float:
    """var(noise)/var(torque) on a record that keeps ``0 ... scored_hz`` when white noise, band-limited to
    ``white_hz`` and scaled to ``snr_db`` (standard definition) *before* a Butterworth low-pass of ``order``
    and ``cutoff_hz``, is what was added (the derivation of reading R1 tried in issue 19):
    ``10^(-SNR/10) * integral_0^scored |H(f)|^2 df / white_hz`` with ``|H|^2 = 1/(1 + (f/f_c)^(2n))``."""
    from scipy.integrate import quad

    top = min(scored_hz, white_hz)
    power, _ = quad(lambda f: 1.0 / (1.0 + (f / cutoff_hz) ** (2 * order)), 0.0, top, limit=500)
    return 10.0 ** (-snr_db / 10.0) * power / white_hz


def inferred_noise_ratio(vaf_val: float, vaf_optim: float) -> float:
    """The noise ratio a published row implies (reading R1): VAF_val = 1 - (r + e)/(1 + r) with
    e = 1 - VAF_optim (validation noise independent of the model error), so r = (1 - VAF_val - e)/VAF_val;
    VAFs in percent."""
    v, e = vaf_val / 100.0, 1.0 - vaf_optim / 100.0
    return (1.0 - v - e) / v


def step_times(time: np.ndarray, k: np.ndarray, window: tuple[float, float], margin: float) -> list[int]:
    """Indices of the samples where the true stiffness ``k`` jumps (first sample at the new level),
    at least ``margin`` seconds inside ``window``."""
    k = np.asarray(k, float)
    if k.ndim == 0 or len(k) < 2:
        return []
    jump = np.abs(np.diff(k))
    big = np.flatnonzero(jump > 0.25 * (np.max(k) - np.min(k)) + 1e-12) + 1
    lo, hi = window
    return [int(i) for i in big if lo + margin <= time[i] <= hi - margin]


def step_ramp_time(time: np.ndarray, khat: np.ndarray, true: np.ndarray, i: int, half: float) -> float:
    """Equivalent ramp duration (s) of the estimate at the step at sample ``i``.

    ``|step height| / max slope``, where the height is that of the true curve (mean over ``half``
    seconds after minus before the step) and the slope the estimate's steepest slope in the step's
    direction within ``half`` seconds of it. A perfect follower gives one sample interval; an estimate
    that does not rise at all gives infinity.
    """
    t = np.asarray(time, float)
    dt = t[1] - t[0]
    near = np.abs(t - t[i]) <= half
    before = near & (t < t[i])
    after = near & (t >= t[i])
    height = float(np.mean(true[after]) - np.mean(true[before]))
    if height == 0 or not before.any() or not after.any():
        return float("nan")
    slope = np.gradient(np.asarray(khat, float), dt)[near] * np.sign(height)
    top = float(np.max(slope))
    return abs(height) / top if top > 0 else float("inf")


def step_captured(time: np.ndarray, khat: np.ndarray, true: np.ndarray, i: int, span: float,
                  skip: float) -> float:
    """Fraction of the true step recovered by the estimate: (mean after - mean before) of the
    estimate over ``skip ... span`` seconds either side of the step at sample ``i``, divided by the
    same of the truth (1 = a perfect step, 0 = no change)."""
    t = np.asarray(time, float)
    d = t - t[i]
    before = (d < -skip) & (d >= -span)
    after = (d >= skip) & (d <= span)
    height = float(np.mean(true[after]) - np.mean(true[before]))
    if height == 0 or not before.any() or not after.any():
        return float("nan")
    return float((np.mean(khat[after]) - np.mean(khat[before])) / height)


def variation_labels(profile: Any) -> dict:
    """``shape`` and ``period_s`` of a stiffness profile (labels of the rows, for trend checks)."""
    period = getattr(profile, "period", None)
    freq = getattr(profile, "frequency", None)
    if period is None and freq:
        period = 1.0 / freq
    return {"shape": str(getattr(profile, "shape", "")), "period_s": float(period) if period else math.nan}


# ---------------------------------------------------------------------------------------- protocol
@dataclasses.dataclass(frozen=True)
class Table1Params:
    """One case of Table I; ``variation`` and ``snr_db`` normally come from the part's sweep."""

    variation: str = param(doc="name of the stiffness variation, a key of 'variations'")
    snr_db: float = param(unit="dB", doc="nominal SNR (dB); .inf = no noise", allow_inf=True)
    variations: dict = param(default_factory=dict, doc="name -> profile of the intrinsic stiffness k(t)")
    noise: Literal["snr_db", "variance_ratio"] = param("variance_ratio",
                                                       doc="how the nominal SNR sets the noise level")
    variance_ratio: dict = param(default_factory=dict,
                                 doc="nominal dB -> var(noise)/var(torque) (noise: variance_ratio)")
    estimators_without_noise: dict = param(default_factory=dict,
                                           doc="estimator -> settings replacing the part's at SNR = inf")
    score: tuple[float, ...] = param((5.0, 35.0), unit="s",
                                     doc="scored interval, in s from the first sample of the analysis window")
    vaf_on: Literal["scored", "window"] = param("scored", doc="samples of the VAFs: scored interval or "
                                                              "the whole analysis window")
    step_half: float = param(2.5, unit="s", gt=0, doc="half width of the neighbourhood of a step")
    step_span: float = param(1.0, unit="s", gt=0, doc="'captured' compares means up to this far from a step")
    step_skip: float = param(0.1, unit="s", ge=0, doc="... leaving out this much either side of the step")
    curve_seeds: tuple[int, ...] = param((0,), doc="seeds whose stiffness curves and images are recorded")
    curve_every: int = param(2, ge=1, doc="the stiffness curves keep every this many samples")
    band_step: float = param(0.5, unit="s", ge=0, doc="grid of the stiffness recorded for every seed "
                                                      "(seed-spread bands); 0 = off")
    image_variations: tuple[str, ...] = param(("sine20",), doc="variations whose |G(jw, t)| image is "
                                                               "recorded (curve seeds only)")
    image_step: float = param(0.5, unit="s", gt=0, doc="time grid of the |G(jw, t)| images")
    bound_orders: tuple[int, ...] = param((), doc="orders N_p of the eq. 14 basis whose best possible RMSE_k "
                                                  "(skirt bound) is recorded, on the curve seeds without noise")
    bound_intervals: dict = param(default_factory=dict,
                                  doc="name -> [start, end] (s from the window's start): other scored intervals "
                                      "of the bound")

    def __post_init__(self):
        if self.variation not in self.variations:
            raise ValueError(f"variation {self.variation!r} is not a key of 'variations' "
                             f"({', '.join(self.variations) or 'empty'})")
        for name, prof in self.variations.items():
            parse_profile(prof, f"variations.{name}")
        if len(self.score) != 2 or not self.score[0] < self.score[1]:
            raise ValueError(f"score must be (start, end) with start < end, got {self.score}")
        if self.noise == "variance_ratio" and math.isfinite(self.snr_db):
            noise_ratio(self.snr_db, self.noise, self.variance_ratio)
        for name, settings in self.estimators_without_noise.items():
            estimators.make(name, settings, f"estimators_without_noise.{name}")


def _case_experiment(exp: Any, p: Table1Params) -> Any:
    """The part's experiment with this case's stiffness profile and output noise."""
    joint = dataclasses.replace(exp.joint, k=parse_profile(p.variations[p.variation], f"variations.{p.variation}"))
    ratio = noise_ratio(p.snr_db, p.noise, p.variance_ratio)
    torque = dataclasses.replace(exp.sensors.torque, noise_rms=None, noise_snr_db=None,
                                 noise_variance_ratio=ratio if ratio > 0 else None)
    sensors = dataclasses.replace(exp.sensors, torque=torque)
    return dataclasses.replace(exp, joint=joint, sensors=sensors)


def _case_estimators(ctx: Context, p: Table1Params) -> dict:
    if math.isfinite(p.snr_db) or not p.estimators_without_noise:
        return dict(ctx.estimators)
    out = {}
    for name, est in ctx.estimators.items():
        over = p.estimators_without_noise.get(name)
        if over:
            base = dataclasses.asdict(est.settings)
            out[name] = estimators.make(name, {**base, **over}, f"estimators_without_noise.{name}")
        else:
            out[name] = est
    return out


def _lowest_line(est: Any, f1: float) -> float:
    """The lowest line an estimate reports its stiffness at (its ``lines_hz``, e.g. a skirt fitted on chosen
    lines), else ``f1`` (the perturbation's lowest line)."""
    lines = getattr(est, "lines_hz", None)
    return float(np.min(lines)) if lines is not None and len(lines) else f1


def _skirt_bounds(ctx: Context, p: Table1Params, t: np.ndarray, truths: dict, lab: dict) -> None:
    """The best possible RMSE_k of the eq. 14 basis (``rmse_k_bound``, estimator 'bound') for each order of
    ``bound_orders``, each scored interval (the part's ``score`` as 'paper' and ``bound_intervals``), each
    truth (the frozen |G(j w_1, t)| of reading R5, the intrinsic k(t)) and each fit (least squares on the
    scored samples: the exact bound; on the whole window: what a fit over the record projects)."""
    tw = t - t[0]
    duration = float(len(t) * (t[1] - t[0]))
    intervals = {"paper": tuple(p.score), **{k: tuple(v) for k, v in p.bound_intervals.items()}}
    for n_p in p.bound_orders:
        B = skirt_basis(int(n_p), tw, duration)
        for iname, window in intervals.items():
            m = scored_mask(t, window)
            for tname, truth in truths.items():
                for fit in ("scored", "window"):
                    ctx.metric("rmse_k_bound", basis_bound(truth, t, m, B, fit), "bound", n_p=int(n_p),
                               interval=iname, truth=tname, fit=fit, **lab)


@dataclasses.dataclass
class _Reference:
    """What every estimate of a case is scored against and drawn beside, on the analysis window."""

    t: np.ndarray                    # time (s)
    s: np.ndarray                    # the scored samples
    lines: np.ndarray                # the excited lines (Hz)
    H1: np.ndarray                   # the true frozen |G(j w_1, t)| at the lowest line (reading R5)
    k_true: np.ndarray               # the intrinsic k(t)
    steps: list[int]                 # samples where k jumps, inside the scored interval
    record: bool                     # a curve seed: stiffness curves (and images) recorded
    grid: np.ndarray | None          # the time grid of the seed-spread bands (None: off)
    tg: np.ndarray | None            # the time grid of the |G(jw, t)| images (None: no image)

    @property
    def f1(self) -> float:
        return float(self.lines[0])


def _record_noise(ctx: Context, y: np.ndarray, y0: np.ndarray, s: np.ndarray) -> None:
    """``noise_variance_ratio`` and ``snr_db_actual`` (standard definition) of the estimation trial's output
    ``y`` (noise-free: ``y0``), over the scored samples ``s`` and the whole window (``..._window``)."""
    for tag, m in (("", s), ("_window", np.ones_like(s))):
        noise = y[m] - y0[m]
        ratio = float(np.var(noise) / np.var(y0[m]))
        ctx.metric("noise_variance_ratio" + tag, ratio)
        ctx.metric("snr_db_actual" + tag, -10 * math.log10(ratio) if ratio > 0 else math.inf)


def _reference(ctx: Context, p: Table1Params, exp: Any, trial: Any) -> _Reference:
    """The truth of the estimation ``trial``, its curves recorded: the stiffness on the paper's time axis (0
    at the start of the scored interval; curve seeds), on the grid of the seed-spread bands, and the
    |G(jw, t)| image (curve seeds of the image variations)."""
    t = trial.time
    lines = np.asarray(exp.perturbation.lines, float)
    H1 = frozen_stiffness(trial, float(lines[0]))
    k_true = trial.truth.at("K", t, t)
    record = ctx.seed in p.curve_seeds
    every = slice(None, None, p.curve_every)
    if record:
        ctx.curve("stiffness", (t - p.score[0])[every], H1[every], series="truth")
        ctx.curve("stiffness", (t - p.score[0])[every], k_true[every], series="k")
    grid = None
    if p.band_step > 0:
        grid = np.arange(t[0], t[-1] + 1e-9, p.band_step)
        ctx.curve("stiffness_grid", grid - p.score[0], np.interp(grid, t, H1), series="truth")
    tg = None
    if record and p.variation in p.image_variations:
        tg = np.arange(t[0], t[-1] + 1e-9, p.image_step)
        Gt = np.abs(trial.truth.frozen_response(lines, tg, t))
        for j, f in enumerate(lines):
            ctx.curve("tf_mag", tg - p.score[0], Gt[:, j], series="truth", freq_hz=float(f))
    return _Reference(t, scored_mask(t, p.score), lines, H1, k_true, step_times(t, k_true, p.score, p.step_half),
                      record, grid, tg)


def _score_estimate(ctx: Context, p: Table1Params, ref: _Reference, name: str, est: Any, trials: tuple,
                    lab: dict, first: bool) -> np.ndarray:
    """Record the VAFs, RMSE_k and (square waves) the step metrics of estimate ``est`` (:func:`table1`);
    ``trials``: the estimation and validation trials; ``first``: the case's first estimator (it also records
    the truth's own ramp time). The estimated stiffness."""
    est_trial, val_trial = trials
    t, s = ref.t, ref.s
    v = s if p.vaf_on == "scored" else np.ones_like(s)
    y, y0, yv = est_trial.output, est_trial.truth.signals["torque"], val_trial.output
    yhat = est.predict(est_trial.input)
    yhat_v = yhat      # the validation trial's input is the estimation trial's (checked by table1)
    for tag, m in (("", v), ("_window", np.ones_like(s))):
        ctx.metric("vaf_self" + tag, vaf(y[m], yhat[m]), name, **lab)
        ctx.metric("vaf_optim" + tag, vaf(y0[m], yhat[m]), name, **lab)
        ctx.metric("vaf_val" + tag, vaf(yv[m], yhat_v[m]), name, **lab)
    khat = np.asarray(est.stiffness(t), float)
    ctx.metric("rmse_k", rmse(ref.H1[s], khat[s]), name, **lab)      # R5: against |G(j w_1, t)|, w_1 = 0.1 Hz
    f_est = _lowest_line(est, ref.f1)
    if not math.isclose(f_est, ref.f1, rel_tol=1e-6):   # its lowest line is another (R12: skirt N_p = 13, 0.9 Hz)
        ctx.metric("rmse_k_own_line", rmse(frozen_stiffness(est_trial, f_est)[s], khat[s]), name,
                   line_hz=f_est, **lab)
    ctx.metric("rmse_k_intrinsic", rmse(ref.k_true[s], khat[s]), name, **lab)
    steps, H1 = ref.steps, ref.H1
    if steps:
        ramps = [step_ramp_time(t, khat, H1, i, p.step_half) for i in steps]
        caught = [step_captured(t, khat, H1, i, p.step_span, p.step_skip) for i in steps]
        ctx.metric("step_ramp_time_s", float(np.median(ramps)), name, n_steps=len(steps), **lab)
        ctx.metric("step_captured", float(np.median(caught)), name, n_steps=len(steps), **lab)
        if first:
            ctx.metric("step_ramp_time_s", float(np.median([step_ramp_time(t, H1, H1, i, p.step_half)
                                                            for i in steps])), "truth",
                       n_steps=len(steps), **lab)
    return khat


def _record_estimate(ctx: Context, p: Table1Params, ref: _Reference, name: str, est: Any, khat: np.ndarray) -> None:
    """The estimate's curves beside the truth's (:func:`_reference`): its stiffness, on the band grid, and
    its |G(jw, t)| image."""
    if ref.record:
        every = slice(None, None, p.curve_every)
        ctx.curve("stiffness", (ref.t - p.score[0])[every], khat[every], series=name, estimator=name)
    if ref.grid is not None:
        ctx.curve("stiffness_grid", ref.grid - p.score[0], np.interp(ref.grid, ref.t, khat), series=name,
                  estimator=name)
    if ref.tg is not None:
        G = np.abs(np.asarray(est.frequency_response(ref.lines, ref.tg)))
        for j, f in enumerate(ref.lines):
            ctx.curve("tf_mag", ref.tg - p.score[0], G[:, j], series=name, estimator=name, freq_hz=float(f))


@register("vanderuit2018.table1", Table1Params, share=lambda p: p.variations[p.variation])
def table1(ctx: Context) -> None:
    """Table I, Figs. 3-4: VAF_self, VAF_optim, VAF_val and RMSE_k of each estimator for one case.

    Metrics per estimator (percent for VAFs, N·m/rad for RMSEs), on the scored interval unless said:

    * ``vaf_self``: prediction from the estimation trial's input against its noisy output (eq. 17);
    * ``vaf_optim``: the same prediction against the noise-free output of the estimation trial;
    * ``vaf_val``: prediction from the validation trial's input against its noisy output;
    * ``vaf_self_window``, ``vaf_optim_window``, ``vaf_val_window``: the same over the whole window;
    * ``rmse_k`` (eq. 18): estimated stiffness |Ĝ(jw_1, t)| at the lowest excited line against the
      true frozen |G(jw_1, t)|; ``rmse_k_intrinsic``: against the intrinsic k(t) (contact ignored);
    * square waves: ``step_ramp_time_s`` (height / steepest slope, median over the steps of the
      scored interval) and ``step_captured`` (fraction of the step recovered within ``step_span``).

    Without estimator: ``noise_variance_ratio`` and ``snr_db_actual`` (standard definition) of the
    estimation trial, over the scored interval and the whole window (``..._window``).
    """
    p = ctx.params
    exp = _case_experiment(ctx.experiment, p)
    ests = _case_estimators(ctx, p)
    lab = variation_labels(exp.joint.k)
    est_trial = sims.simulate(exp, ctx.seed, name="estimation")
    val_trial = sims.simulate(exp, ctx.seed, name="validation", replicate=1)
    if not np.array_equal(est_trial.input, val_trial.input):
        raise RuntimeError("the validation trial's input differs from the estimation trial's")
    _record_noise(ctx, est_trial.output, est_trial.truth.signals["torque"], scored_mask(est_trial.time, p.score))
    ref = _reference(ctx, p, exp, est_trial)
    if ref.record and not math.isfinite(p.snr_db) and p.bound_orders:
        _skirt_bounds(ctx, p, ref.t, {"frozen": ref.H1, "intrinsic": ref.k_true}, lab)
    first = True                             # the first estimate scored also records the truth's own ramp time
    for name, estimator in ests.items():
        try:
            est = fit_gated(estimator, est_trial)
        except Refused as exc:               # the output gate: this method refused, the other kept
            ctx.refused(name, exc)
            continue
        khat = _score_estimate(ctx, p, ref, name, est, (est_trial, val_trial), lab, first=first)
        first = False
        _record_estimate(ctx, p, ref, name, est, khat)
