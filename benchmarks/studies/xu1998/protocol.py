"""Protocols of Xu & Hollerbach (1998), "Identification of human joint mechanical properties from single
trial data" (FSEWLS on a time-varying elbow).

One case simulates one trial of the torque-driven elbow ``I θ'' + B(t) θ' + K(t) θ = τ_v + τ_p``
(paper eq. 7), fits FSEWLS (eqs. 3-6) and scores the estimated I(t), B(t), K(t) against the truth on
the scored window (the acquired record minus ``discard`` seconds at each end) with VAFM and VAFV
(eq. 8), RMSE, the mean error, and the VAF of the output prediction.

The part's parameters (or its sweep) say what this case changes in the configured experiment:
the frequency ``f_v`` of the parameter variation (which also sets the movement frequency), the
condition (posture: θ_n = 0; movement: θ_n = A sin 2π f_v t, produced by the voluntary torque), the
shape of K(t), the angle noise (NSR), the damping ratio, and the estimator's ambiguous settings.

References
----------
Xu, Y. & Hollerbach, J. M. (1998). IEEE Trans. Biomed. Eng. 45(9): eqs. 3-8, Sec. III (Figs. 2-3),
Sec. IV-B (calibration arm, Fig. 5), Appendices A-B.
"""
from __future__ import annotations

import dataclasses
from typing import Literal

import numpy as np

from jointbench import sims
from jointbench.benchmarks.metrics import rmse, vafm, vafv
from jointbench.core.scores import vaf
from jointbench.benchmarks.protocols import Context, register
from jointbench.benchmarks.scoring import fit_gated
from jointbench.core.ensemble import valid_mask
from jointbench.core.schema import param, parse
from jointbench.sims.apparatus import TorqueDrive
from jointbench.sims.profile import Sine, Square

OUTPUTS = ("filtered_torque", "torque", "angle")


@dataclasses.dataclass(frozen=True)
class TrackParams:
    """What one case changes in the configured experiment and estimator, and how it is scored."""

    condition: Literal["posture", "movement"] = param("posture", doc="posture: theta_n = 0; movement: "
                                                     "theta_n = movement_amplitude sin(2 pi f_v t)")
    f_v: float | None = param(None, unit="Hz", gt=0, doc="frequency of the parameter variation (K, and B "
                              "when it is a profile) and of the movement; none = as configured")
    shape: Literal["sine", "square"] | None = param(None, doc="shape of K(t); none = as configured")
    movement_amplitude: float = param(0.5, unit="rad", gt=0, doc="amplitude of the voluntary movement")
    nsr: float | None = param(None, ge=0, doc="measurement noise var(noise)/var(signal) on the channel "
                              "'noise_on'; none = as configured")
    noise_on: Literal["torque", "angle"] = param("torque", doc="channel that 'nsr' sets: the regression "
                                                 "output (torque) or the angle")
    zeta: float | None = param(None, ge=0, doc="constant damping ratio; none = as configured")
    posture_highpass: bool = param(False, doc="apply the high-pass H in posture too (movement: always)")
    measured_voluntary: bool = param(False, doc="the torque sensor sees the voluntary torque too "
                                     "(tau_meas = tau_p + tau_v); default: tau_p only")
    svf_causal: bool | None = param(None, doc="override the estimator's svf_causal")
    svf_cutoff_means: Literal["-3dB", "a"] | None = param(None, doc="override the estimator's "
                                                          "svf_cutoff_means")
    estimator_settings: dict = param(default_factory=dict, doc="further overrides of the estimator's "
                                     "settings (e.g. svf_cutoff, forgetting), parsed strictly")
    discard: float = param(4.0, unit="s", ge=0, doc="seconds of the acquired record not scored at each "
                           "end (filter and EWLS transients); at least the estimator's own transient")
    output: Literal["filtered_torque", "torque", "angle"] = param(
        "filtered_torque", doc="signal whose prediction gives 'vaf_output' (all three are recorded)")
    paired_noise_free: bool = param(False, doc="also fit the same record without the noise and record "
                                    "the drops of the VAFs")
    paired_settings: bool = param(False, doc="also fit the same record with the part's own estimator_settings "
                                  "(this variant's left out) and record abs_change_<metric>, the absolute change "
                                  "of each VAF (how much a setting changes the results, check X8)")
    curve_seeds: int = param(1, ge=0, doc="the lowest seeds whose time courses are stored for the figures")
    curve_params: tuple[str, ...] = param(("K", "B", "I"), doc="parameters whose time courses are stored")
    curve_rate: float = param(50.0, unit="Hz", gt=0, doc="rate of the stored time courses")
    estimator: str = param("fsewls", doc="estimator of the part scored")
    regressors: Literal["filtered", "exact"] = param("filtered", doc="filtered: the estimator's own H and L "
                                                    "on the measured signals; exact: a control that feeds the "
                                                    "estimator's EWLS the simulation's exact perturbed response "
                                                    "delta theta'', delta theta', delta theta and perturbation "
                                                    "torque (eq. 2; noise free, voluntary part separated exactly)")
    variants: dict = param(default_factory=dict, doc="name -> overrides of these parameters (readings part)")
    variant: str | None = param(None, doc="which entry of 'variants' this case uses")

    def __post_init__(self):
        bad = [c for c in self.curve_params if c not in ("I", "B", "K", "zeta")]
        if bad:
            raise ValueError(f"key 'curve_params': unknown parameter {bad[0]!r}; allowed: I, B, K, zeta")
        if self.regressors == "exact" and (self.nsr or self.measured_voluntary):
            raise ValueError("key 'regressors': 'exact' is a noise-free control of the perturbed response "
                             "(no nsr, no measured_voluntary)")
        if self.variant is not None and self.variant not in self.variants:
            raise ValueError(f"key 'variant': {self.variant!r} is not in 'variants' "
                             f"({', '.join(self.variants) or 'none given'})")


def resolve_variant(p: TrackParams) -> TrackParams:
    """The parameters with the named variant's overrides applied (parsed strictly)."""
    if p.variant is None:
        return p
    base = {f.name: getattr(p, f.name) for f in dataclasses.fields(p) if f.name not in ("variants", "variant")}
    over = p.variants[p.variant] or {}
    for key in ("variants", "variant"):
        if key in over:
            raise ValueError(f"variant {p.variant!r}: key {key!r} cannot be overridden")
    out = parse(TrackParams, {**base, **over}, f"params.variants.{p.variant}")
    return dataclasses.replace(out, variants=p.variants, variant=p.variant)


# ------------------------------------------------------------------------------------ the experiment
def _with_frequency(profile, f_v: float | None, shape: str | None):
    """The profile at frequency ``f_v`` and of ``shape`` (sine or square of the same mean and amplitude)."""
    if not isinstance(profile, (Sine, Square)):
        if shape is not None:
            raise ValueError(f"key 'shape': the configured profile is {type(profile).__name__}, only a sine "
                             f"or square profile can change shape")
        return profile
    cls = {"sine": Sine, "square": Square, None: type(profile)}[shape]
    if f_v is None:
        f, T = profile.frequency, profile.period
    else:
        f, T = f_v, None
    return cls(mean=profile.mean, amplitude=profile.amplitude, frequency=f, period=T, phase=profile.phase)


def case_experiment(exp: sims.Experiment, p: TrackParams) -> sims.Experiment:
    """The configured experiment with this case's frequency, shape, damping ratio, condition and noise."""
    joint = exp.joint
    changes = {"K": _with_frequency(joint.K, p.f_v, p.shape)}
    if joint.B is not None:
        changes["B"] = _with_frequency(joint.B, p.f_v, None)
    if p.zeta is not None:
        if joint.damping_ratio is None:
            raise ValueError("key 'zeta': the configured joint gives B directly, not a damping ratio")
        changes["damping_ratio"] = p.zeta
    joint = dataclasses.replace(joint, **changes)
    vol = exp.voluntary
    if p.condition == "movement":
        f_move = p.f_v if p.f_v is not None else getattr(joint.K, "frequency", None)
        if f_move is None:
            raise ValueError("condition 'movement' needs f_v (or a K profile given by its frequency)")
        vol = dataclasses.replace(vol, movement_amplitude=p.movement_amplitude, movement_frequency=f_move)
    else:
        vol = dataclasses.replace(vol, movement_amplitude=0.0, movement_frequency=None)
    sensors = exp.sensors
    if p.nsr is not None:
        channel = getattr(sensors, p.noise_on)
        channel = dataclasses.replace(channel, noise_variance_ratio=p.nsr or None, noise_rms=None,
                                      noise_snr_db=None)
        sensors = dataclasses.replace(sensors, **{p.noise_on: channel})
    return dataclasses.replace(exp, joint=joint, voluntary=vol, sensors=sensors)


def case_estimator(est, p: TrackParams):
    """The configured estimator with this case's overrides (high-pass off in posture unless asked)."""
    s = est.settings
    if p.estimator_settings:
        current = {f.name: getattr(s, f.name) for f in dataclasses.fields(s)}
        s = parse(type(s), {**current, **p.estimator_settings}, f"params.estimator_settings ({est.name})")
    changes = {}
    if p.condition == "posture" and not p.posture_highpass:
        changes["highpass_cutoff"] = None
    if p.svf_causal is not None:
        changes["svf_causal"] = p.svf_causal
    if p.svf_cutoff_means is not None:
        changes["svf_cutoff_means"] = p.svf_cutoff_means
    return type(est)(dataclasses.replace(s, **changes)) if changes or s is not est.settings else est


# ------------------------------------------------------------------------------------- output signals
@dataclasses.dataclass(frozen=True)
class _Frozen:
    """A joint whose I, B, K are given on a time grid (for simulating the estimated model)."""

    t: np.ndarray
    I: np.ndarray
    B: np.ndarray
    K: np.ndarray

    def coefficients_at(self, t):
        """I, B, K linearly interpolated at ``t`` (:func:`numpy.interp`)."""
        return tuple(np.interp(t, self.t, v) for v in (self.I, self.B, self.K))


def output_vafs(fit, trial, keep: np.ndarray, signals=OUTPUTS) -> dict[str, float]:
    """VAF (%) of the candidate 'output predictions' named in ``signals`` (default all three) on the scored
    samples.

    - ``filtered_torque``: ``y = L H tau`` against ``Phi^T Theta_hat`` (eq. 5: the regression's own output);
    - ``torque``: ``H tau`` against ``I_hat theta~'' + B_hat theta~' + K_hat theta~``, derivatives of the
      high-passed measured angle by central differences;
    - ``angle``: ``theta~ = H theta`` against the response of the estimated time-varying model to ``H tau``
      (the torque-driven system's own output), started from the measured state at the window's start.
    """
    theta, tau = fit.highpassed[0, 0], fit.highpassed[1, 0]   # what the estimate fitted: H theta, H tau
    out = {}
    if "filtered_torque" in signals:
        out["filtered_torque"] = vaf(fit.filtered_torque[0, keep], fit.predicted_filtered_torque[0, keep])
    if "torque" not in signals and "angle" not in signals:
        return out
    dt = 1.0 / trial.fs
    d1 = np.gradient(theta, dt, edge_order=2)
    if "torque" in signals:
        d2 = np.gradient(d1, dt, edge_order=2)
        pred = fit.I * d2 + fit.B * d1 + fit.K * theta
        out["torque"] = vaf(tau[keep], pred[keep])
    if "angle" not in signals:
        return out
    idx = np.flatnonzero(keep)
    i0, i1 = idx[0], idx[-1] + 1
    t = np.arange(i1 - i0) * dt
    model = _Frozen(t, fit.I[i0:i1], fit.B[i0:i1], fit.K[i0:i1])
    with np.errstate(all="ignore"):   # an estimate with K_hat or B_hat < 0 makes the model unstable
        # the estimated model's own response: an analytic computation whatever backend made the trial
        resp = sims.BACKENDS.get("ltv")().run(model, TorqueDrive(), tau[i0:i1], np.zeros(i1 - i0), trial.fs,
                                              x0=(float(theta[i0]), float(d1[i0])))
        ok = np.all(np.isfinite(resp.angle)) and np.max(np.abs(resp.angle)) <= 100 * np.max(np.abs(theta[i0:i1]))
        out["angle"] = vaf(theta[i0:i1], resp.angle) if ok else float("nan")   # NaN: the model diverged
    return out


# ------------------------------------------------------------------------------- exact-derivative control
@dataclasses.dataclass(frozen=True)
class _ExactFit:
    """I, B, K from EWLS on exact regressors (the part of an FSEWLS estimate the scoring reads)."""

    I: np.ndarray
    B: np.ndarray
    K: np.ndarray
    y: np.ndarray
    yhat: np.ndarray

    def damping_ratio(self) -> np.ndarray:
        ki = self.K * self.I
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.where(ki > 0, self.B / (2.0 * np.sqrt(np.abs(ki))), np.nan)


def exact_fit(est, trial) -> _ExactFit:
    """EWLS of the estimator's settings (forgetting, init_window) fed the exact perturbed response of the
    simulated joint and the perturbation torque (eq. 2): no high-pass, no state-variable filter, no sensors.

    The states come from the simulator's own LTV integrator run on the acquired perturbation torque
    (``truth.signals['command']``) alone with the true I(t), B(t), K(t) of the trial, so
    ``I dtheta'' + B dtheta' + K dtheta = tau_p`` holds sample by sample. The joint is linear, so this is the
    perturbed response with the voluntary movement separated exactly (posture and movement alike); what
    is left is the EWLS itself (its forgetting lag).
    """
    from jointbench.estimators.fsewls import ewls_regression

    s, fs, truth = est.settings, trial.fs, trial.truth
    n = trial.n
    t = np.arange(n) / fs
    joint = _Frozen(t, *(np.broadcast_to(np.asarray(getattr(truth, k), float), (n,)).copy() for k in "IBK"))
    tau = np.asarray(truth.signals["command"], float)
    resp = sims.BACKENDS.get("ltv")().run(joint, TorqueDrive(), tau, np.zeros(n), fs)
    Phi = np.stack([resp.acceleration, resp.velocity, resp.angle], axis=-1)[None]
    theta = ewls_regression(Phi, tau[None], fs, s.forgetting, s.init_window)
    return _ExactFit(I=theta[:, 0], B=theta[:, 1], K=theta[:, 2], y=tau, yhat=np.einsum("ni,ni->n", Phi[0], theta))


# ------------------------------------------------------------------------------------------- scoring
def _scores(fit, truth, keep: np.ndarray, dt: float) -> dict[str, float]:
    out = {}
    for name in ("I", "B", "K"):
        x = np.broadcast_to(np.asarray(getattr(truth, name), float), keep.shape)[keep]
        xh = np.asarray(getattr(fit, name), float)[keep]
        out[f"vafm_{name}"] = vafm(x, xh)
        out[f"vafv_{name}"] = vafv(x, xh, dt)
        out[f"rmse_{name}"] = rmse(x, xh)
        out[f"mean_err_{name}"] = float(np.mean(xh) - np.mean(x))
        out[f"err_pct_{name}"] = float(100.0 * (np.mean(xh) - np.mean(x)) / np.mean(x))
        out[f"abs_err_pct_{name}"] = abs(out[f"err_pct_{name}"])
        out[f"mean_{name}"] = float(np.mean(xh))
        out[f"true_mean_{name}"] = float(np.mean(x))
    zeta = fit.damping_ratio()[keep]
    out["mean_zeta"] = float(np.nanmean(zeta))
    I, B, K = (np.broadcast_to(np.asarray(getattr(truth, k), float), keep.shape)[keep] for k in "IBK")
    out["true_mean_zeta"] = float(np.mean(B / (2 * np.sqrt(K * I))))
    return out


def scored_window(n: int, fs: float, discard: float, valid: np.ndarray | None = None) -> np.ndarray:
    """Mask of the samples at least ``discard`` s from both ends where the estimate is ``valid``
    (:func:`jointbench.core.ensemble.valid_mask`: past the estimator's own transients)."""
    m = int(round(discard * fs))
    keep = np.zeros(n, bool)
    keep[m:n - m] = True
    if valid is not None:
        keep &= valid
    if keep.sum() < 2:
        raise ValueError(f"discard: {discard:g} s at each end and the estimate's transients leave nothing of "
                         f"{n / fs:g} s")
    return keep


def response_params(p: TrackParams) -> tuple:
    """What of a case's parameters changes the simulated response (sensors and noise do not)."""
    p = resolve_variant(p)
    return (p.condition, p.f_v, p.shape, p.zeta, p.movement_amplitude)


@register("xu1998.track", TrackParams, share=response_params)
def track(ctx: Context) -> None:
    """Simulate, fit FSEWLS, score I(t), B(t), K(t) and the output prediction (Xu & Hollerbach 1998).

    Metrics (estimator column = the estimator's name): ``vafm_X``, ``vafv_X`` (eq. 8, floor 1, VAFV as
    the time integral), ``rmse_X``, ``mean_err_X`` (mean X_hat - mean X), ``err_pct_X``,
    ``abs_err_pct_X`` for X in I, B, K; ``mean_zeta`` and ``true_mean_zeta``; ``vaf_output`` (the
    signal named by ``output``) and ``vaf_output_<signal>`` for each candidate of :func:`output_vafs`;
    with ``paired_noise_free``, ``drop_<metric>`` = metric without noise - metric with noise on the
    same record; with ``paired_settings``, ``abs_change_<metric>`` = |metric - metric with the part's own
    estimator settings| on the same record; ``vafv_K_minus_vafv_B`` (check X7: K tracked worst). Labels:
    ``condition`` and ``f_v`` (Hz, when set).

    References
    ----------
    Xu, Y. & Hollerbach, J. M. (1998). Identification of human joint mechanical properties from single trial
    data. IEEE Trans. Biomed. Eng. 45(9), 1051-1060: Sec. III-B (Figs. 2, 3; 'A 10%-15% variation of lambda
    did not change the following simulated results much').
    """
    p = resolve_variant(ctx.params)
    if p.estimator not in ctx.estimators:
        raise KeyError(f"estimator {p.estimator!r} must be listed in the part's estimators")
    exp = case_experiment(ctx.experiment, p)
    est = case_estimator(ctx.estimators[p.estimator], p)
    trial = sims.simulate(exp, ctx.seed)
    if p.measured_voluntary and exp.voluntary.active:
        trial = trial.replace(torque=trial.torque + np.asarray(trial.truth.signals["voluntary"]))
    if p.regressors == "filtered":
        fit = fit_gated(est, trial)
    else:
        fit = exact_fit(est, trial)
    keep = scored_window(trial.n, trial.fs, p.discard, valid_mask(fit) if p.regressors == "filtered" else None)
    dt = 1.0 / trial.fs
    labels = {"condition": p.condition}
    if p.f_v is not None:
        labels["f_v"] = p.f_v
    scores = _scores(fit, trial.truth, keep, dt)
    if p.regressors == "filtered":
        outs = output_vafs(fit, trial, keep)
        scores["vaf_output"] = outs[p.output]
        scores.update({f"vaf_output_{k}": v for k, v in outs.items()})
    else:   # the exact regression's own output: tau against Phi^T Theta_hat
        scores["vaf_output"] = vaf(fit.y[keep], fit.yhat[keep])
    scores["scored_s"] = keep.sum() * dt
    scores["vafv_K_minus_vafv_B"] = scores["vafv_K"] - scores["vafv_B"]
    if p.paired_noise_free:   # the same record (same perturbation) without the noise of 'nsr'
        exp0 = case_experiment(ctx.experiment, dataclasses.replace(p, nsr=0.0))
        clean = sims.simulate(exp0, ctx.seed)
        if p.measured_voluntary and exp.voluntary.active:
            clean = clean.replace(torque=clean.torque + np.asarray(clean.truth.signals["voluntary"]))
        fit0 = fit_gated(est, clean)
        s0 = _scores(fit0, trial.truth, keep, dt)
        o0 = output_vafs(fit0, clean, keep, signals=(p.output,))   # only this drop is recorded
        s0["vaf_output"] = o0[p.output]
        for k in ("vafm_K", "vafv_K", "vafm_B", "vafv_B", "vafm_I", "vafv_I", "vaf_output"):
            scores[f"drop_{k}"] = s0[k] - scores[k]
    if p.paired_settings:     # the same record fitted with the part's own settings (check X8)
        base = case_estimator(ctx.estimators[p.estimator],
                              dataclasses.replace(p, estimator_settings=ctx.params.estimator_settings))
        fit1 = fit_gated(base, trial) if p.regressors == "filtered" else exact_fit(base, trial)
        s1 = _scores(fit1, trial.truth, keep, dt)
        s1["vaf_output"] = (output_vafs(fit1, trial, keep, signals=(p.output,))[p.output]
                            if p.regressors == "filtered" else vaf(fit1.y[keep], fit1.yhat[keep]))
        for k in ("vafm_K", "vafv_K", "vafm_B", "vafv_B", "vafm_I", "vafv_I", "vaf_output"):
            scores[f"abs_change_{k}"] = abs(scores[k] - s1[k])
    for k, v in scores.items():
        ctx.metric(k, v, est.name, **labels)
    if ctx.seed < p.curve_seeds:   # the lowest seeds (numbered from 0 by default)
        t = exp.acquired_times()
        step = max(1, int(round(trial.fs / p.curve_rate)))
        sel = np.flatnonzero(keep)[::step]
        for name in p.curve_params:
            if name == "zeta":
                true = trial.truth.B / (2 * np.sqrt(trial.truth.K * trial.truth.I))
                ctx.curve("zeta", t[sel], fit.damping_ratio()[sel], series="estimate", **labels)
                ctx.curve("zeta", t[sel], np.broadcast_to(true, keep.shape)[sel], series="truth", **labels)
                continue
            ctx.curve(name, t[sel], np.asarray(getattr(fit, name))[sel], series="estimate", **labels)
            ctx.curve(name, t[sel], np.broadcast_to(np.asarray(getattr(trial.truth, name), float),
                                                    keep.shape)[sel], series="truth", **labels)



# ------------------------------------------------------------------------ the paper's arithmetic (X9)
@dataclasses.dataclass(frozen=True)
class RatioParams:
    """The stated tracking limit whose ratio to the state-variable filter's cutoff Sec. III-B gives."""

    variation_limit: float = param(0.5, unit="Hz", gt=0, doc="the maximum parameter variation Sec. III-B states "
                                   "('should not be more than 0.5 Hz as indicated in Fig. 2(b)')")
    estimator: str = param("fsewls", doc="the estimator whose svf_cutoff (L's cutoff, eq. 4) is used")


def filter_ratios(svf_cutoff: float, variation_limit: float) -> dict[str, float]:
    """The ratio Sec. III-B states between the parameter variation and the cutoff of L, both ways round.

    Parameters
    ----------
    svf_cutoff : float
        Cutoff of the state-variable filter L (Hz; 3.2 in the paper).
    variation_limit : float
        The maximum frequency of the parameter variation (Hz; 0.5 in the paper).

    Returns
    -------
    dict
        ``cutoff_over_variation`` (the order under which the printed 'about 6.4' is possible, reading R22)
        and ``variation_over_cutoff`` (the order as printed: 'the ratio of the parameter variation frequency
        to the filter cutoff frequency').

    References
    ----------
    Xu & Hollerbach (1998), Sec. III-B ('The ratio of the parameter variation frequency to the filter cutoff
    frequency in (4) is about 6.4'); Appendix A ('the ratio of the frequencies of the parameter variation
    and the low-pass filter must be smaller than one').
    """
    return {"cutoff_over_variation": svf_cutoff / variation_limit,
            "variation_over_cutoff": variation_limit / svf_cutoff}


@register("xu1998.filter_ratio", RatioParams)
def filter_ratio(ctx: Context) -> None:
    """X9: the paper's ratio of L's cutoff (the configured estimator's ``svf_cutoff``) to the stated limit of
    the parameter variation (Sec. III-B), arithmetic on its own numbers: no simulation."""
    p = ctx.params
    if p.estimator not in ctx.estimators:
        raise KeyError(f"estimator {p.estimator!r} must be listed in the part's estimators")
    for name, v in filter_ratios(ctx.estimators[p.estimator].settings.svf_cutoff, p.variation_limit).items():
        ctx.metric(name, v, p.estimator)
