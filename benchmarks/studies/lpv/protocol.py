"""Protocol of the lpv study: K(theta) from a single trial with a slow imposed movement.

``lpv.kmap``: one case is one movement (its frequency and range, from the sweep) of the part's experiment
(a joint whose stiffness depends on the angle, ``position_dependent``, moved by a ``moving`` perturbation),
with its reflex gain when the joint has a reflex pathway (``reflex_gain``, the sweep), and one seed. Each
answer is scored against the true K(theta) (the joint model's own function) on a grid over the central
``coverage`` of the range the slow movement visits:

* the parameter-varying estimators (``pv_irf``; ``pv_parallel_cascade``, which adds a reflex pathway),
  scheduled on the slow angle: K(theta) with its band;
* ``fsewls`` mapped through theta: FSEWLS's K-hat(t) (the movement high-passed out, Xu & Hollerbach's
  frequency separation) on its valid, scored samples, regressed on the slow angle by a polynomial of the
  same degree as pv_irf's basis (``n_basis - 1``; its coefficients by least squares), the way a user of a
  time-varying method would read K(theta) from K(t).

Every method is told the movement's speed, as the experimenter who imposed it knows it (never the
truth): the slow angle's cutoff (``slow_cutoff`` of the parameter-varying estimators) and FSEWLS's
high-pass edge are ``cutoff_factor`` times the movement's frequency, at least ``min_cutoff``.

The reflex (a joint with a ``reflex`` pathway): its gain is ``reflex_gain`` at the movement's mean angle and
changes linearly with the slow angle, by ``reflex_gain_change`` times itself at the part's movement's ends
(rising with dorsiflexion for a positive change), :func:`with_reflex`.

Metrics (per estimator): ``kmap_rmse`` (N·m/rad) and ``kmap_rmse_pct`` (of the mean true K over the grid),
``kmap_mean_error_pct`` (the signed mean error: the bias a reflex gives), ``kmap_max_error``; for a band,
``band_coverage`` (fraction of grid points whose true K lies in it) and ``band_halfwidth`` (mean, N·m/rad);
for an estimate with a reflex pathway, ``reflex_kept`` (1 or 0) and, when kept, ``reflex_gain_rmse_pct``
(its static gain along the grid against the true G(theta), % of the mean true gain); ``vaf_output`` and
``fit_time_s``. Case level: ``range_rad`` (the slow movement's span), ``speed_rad_s`` (its rms velocity),
with a reflex ``reflex_share_pct`` (the reflex torque's share of the torque the perturbation evokes: its VAF
of the noise-free torque, both high-passed at the case's cutoff, as the reflex study's share). ``fs``
acquires the case at another rate (the response simulated once for every rate, :func:`_share`). Curves for
the figure (seed 0): K(theta) of the truth, each method and each band; with a reflex, G(theta).

References
----------
Sobhani Tehrani & Kearney (2022), the parameter-varying parallel cascade (K scheduled on the ankle's
position; its abstract: reflex gain rising with dorsiflexion); Xu & Hollerbach (1998), FSEWLS (the frequency
separation of a voluntary movement).
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np

from jointbench import sims
from jointbench.core.scores import vaf
from jointbench.benchmarks.protocols import Context, register
from jointbench.benchmarks.compare.protocol import impedance
from jointbench.benchmarks.scoring import fit_timed, scored_samples
from jointbench.core.ensemble import valid_mask
from jointbench.core.errors import InputError, Refused
from jointbench.estimators.pv_irf import slow_part
from jointbench.core.schema import param
from jointbench.sims.profile import parse_profile


@dataclasses.dataclass(frozen=True)
class KmapParams:
    """One slow movement (from the sweep) and how K(theta) is scored."""

    movement_frequency: float = param(0.1, unit="Hz", gt=0, doc="frequency of the sine movement (its speed)")
    range_scale: float = param(1.0, gt=0, doc="amplitude of the movement as a fraction of the part's")
    cutoff_factor: float = param(3.0, gt=1, doc="slow-angle cutoff and FSEWLS high-pass: this many times the "
                                                "movement's frequency")
    min_cutoff: float = param(0.3, unit="Hz", gt=0, doc="... but at least this")
    coverage: float = param(0.9, gt=0, le=1, doc="the grid covers this central fraction of the visited range")
    points: int = param(21, ge=3, doc="grid points of K(theta)")
    discard: float = param(3.0, unit="s", ge=0, doc="seconds not scored at each end (FSEWLS's start-up)")
    fs: float | None = param(None, unit="Hz", gt=0, doc="the acquired rate (none: the part's acquisition's)")
    reflex_gain: float = param(0.0, unit="N.m.s/rad", ge=0, doc="reflex gain at the movement's mean angle (a joint "
                                                                "with a reflex pathway; 0: no reflex torque)")
    reflex_gain_change: float = param(0.0, ge=-1, le=1, doc="the gain at the part's movement's ends: (1 +- this) "
                                                            "times reflex_gain, linear in the slow angle between")


def with_movement(exp, p: KmapParams):
    """The experiment with the case's movement: the part's sine at ``movement_frequency``, its amplitude
    times ``range_scale`` (the mean kept)."""
    pert = exp.perturbation
    if getattr(pert, "kind", "") != "moving":
        raise ValueError("lpv.kmap needs a 'moving' perturbation (a slow movement plus a perturbation)")
    mv = pert.movement
    move = parse_profile({"shape": "sine", "mean": float(getattr(mv, "mean", 0.0)),
                          "amplitude": float(getattr(mv, "amplitude", 0.0)) * p.range_scale,
                          "frequency": p.movement_frequency}, "movement")
    return dataclasses.replace(exp, perturbation=dataclasses.replace(pert, movement=move))


def with_rate(exp, p: KmapParams):
    """The experiment acquired at the case's rate ``fs`` (unchanged when it is none)."""
    if p.fs is None:
        return exp
    return dataclasses.replace(exp, acquisition=dataclasses.replace(exp.acquisition, fs=p.fs))


def with_reflex(exp, p: KmapParams):
    """The experiment with the case's reflex gain, a function of the slow angle: ``G(theta) = G0 (1 + c (theta -
    mean) / A)`` (``G0 = reflex_gain``, ``c = reflex_gain_change``, ``mean`` and ``A`` the part's movement's
    mean and amplitude), written as the time profile it is along the case's movement (a sine in phase with
    it, of amplitude ``G0 c range_scale``). Unchanged for a joint without a reflex pathway and a gain of 0."""
    if exp.reflex is None:
        if p.reflex_gain:
            raise ValueError("lpv.kmap: reflex_gain needs a joint with a 'reflex' pathway")
        return exp
    g = p.reflex_gain
    if g and p.reflex_gain_change:
        g = {"shape": "sine", "mean": g, "amplitude": g * p.reflex_gain_change * p.range_scale,
             "frequency": p.movement_frequency}
    return dataclasses.replace(exp, reflex=dataclasses.replace(exp.reflex, gain=parse_profile(g, "gain")))


def reflex_gain_true(part_movement, p: KmapParams, theta: np.ndarray) -> np.ndarray:
    """The true reflex gain ``G(theta)`` of :func:`with_reflex` at slow angles ``theta``."""
    mean, amp = float(getattr(part_movement, "mean", 0.0)), float(getattr(part_movement, "amplitude", 0.0))
    return p.reflex_gain * (1.0 + p.reflex_gain_change * (np.asarray(theta, float) - mean) / amp)


def _highpassed(x: np.ndarray, fs: float, cutoff: float) -> np.ndarray:
    return x - slow_part(x, fs, cutoff)


def _map_through(theta: np.ndarray, khat: np.ndarray, degree: int, grid: np.ndarray) -> np.ndarray:
    """K-hat(t) regressed on theta(t) by a polynomial of ``degree`` (least squares), read on ``grid``."""
    c = np.polynomial.polynomial.polyfit(theta, khat, degree)
    return np.polynomial.polynomial.polyval(grid, c)


def _share(p: KmapParams) -> tuple:
    """What of a case's parameters decides its simulated response (not the acquired rate, nor the scoring)."""
    return (p.movement_frequency, p.range_scale, p.reflex_gain, p.reflex_gain_change)


@register("lpv.kmap", KmapParams, share=_share)
def kmap(ctx: Context) -> None:
    """pv_irf's K(theta) and FSEWLS's K-hat(t) mapped through theta(t), against the truth (module docstring)."""
    p = ctx.params
    exp = with_rate(with_reflex(with_movement(ctx.experiment, p), p), p)
    joint = exp.joint
    if not hasattr(joint, "stiffness_at"):
        raise ValueError("lpv.kmap needs a joint whose stiffness depends on the angle (model position_dependent)")
    trial = impedance(sims.simulate(exp, ctx.seed))
    cutoff = max(p.min_cutoff, p.cutoff_factor * p.movement_frequency)
    t = trial.time
    keep = scored_samples(t, p.discard)
    sched = np.asarray(trial.truth.signals["scheduling"])
    lo, hi = np.quantile(sched[keep], [(1 - p.coverage) / 2, (1 + p.coverage) / 2])
    grid = np.linspace(lo, hi, p.points)
    k_true = joint.stiffness_at(grid)
    ctx.metric("range_rad", float(np.ptp(sched[keep])))
    ctx.metric("speed_rad_s", float(np.sqrt(np.mean(np.gradient(sched, t)[keep] ** 2))))
    ctx.metric("cutoff_hz", cutoff)
    signals = trial.truth.signals
    if "reflex_torque" in signals:
        hp = {k: _highpassed(np.asarray(signals[k], float), trial.fs, cutoff)[keep]
              for k in ("torque", "reflex_torque")}
        ctx.metric("reflex_share_pct", vaf(hp["torque"], hp["reflex_torque"], undefined="nan"))
    g_true = reflex_gain_true(ctx.experiment.perturbation.movement, p, grid) if p.reflex_gain else None
    if ctx.seed == 0:
        ctx.curve("k_theta", grid, k_true, series="truth")
        if g_true is not None:
            ctx.curve("reflex_gain", grid, g_true, series="truth")
    for name, estimator in ctx.estimators.items():
        settings = estimator.settings
        if getattr(settings, "schedule", None) == "angle_slow":
            settings = dataclasses.replace(settings, slow_cutoff=cutoff)
        elif name == "fsewls":
            settings = dataclasses.replace(settings, highpass_cutoff=cutoff)
        est_obj = type(estimator)(settings)
        try:
            est, seconds = fit_timed(est_obj, trial)
        except Refused as exc:               # the output gate: this method's fit refused, the others kept
            ctx.refused(name, exc)
            continue
        except InputError as exc:
            ctx.metric("not_fitted", math.nan, name, reason=str(exc))
            continue
        ctx.metric("fit_time_s", seconds, name)
        m = keep & valid_mask(est, t)
        if hasattr(est, "stiffness_at"):
            k_hat = est.stiffness_at(grid)
            blo, bhi = est.stiffness_band(grid)
            ctx.metric("band_coverage", float(np.mean((k_true >= blo) & (k_true <= bhi))), name)
            ctx.metric("band_halfwidth", float(np.mean(bhi - blo) / 2), name)
            degree = len(est.coef) - 1
            if ctx.seed == 0:
                ctx.curve("k_theta", grid, blo, series="band low", estimator=name)
                ctx.curve("k_theta", grid, bhi, series="band high", estimator=name)
        else:
            degree = int(ctx.estimators["pv_irf"].settings.n_basis) - 1 if "pv_irf" in ctx.estimators else 3
            slow = slow_part(trial.angle, trial.fs, cutoff)
            k_hat = _map_through(slow[m], np.asarray(est.stiffness(t), float)[m], degree, grid)
            if ctx.seed == 0:
                step = max(1, int(round(trial.fs / 2)))
                sel = np.flatnonzero(m)[::step]
                ctx.curve("k_of_t", slow[sel], np.asarray(est.stiffness(t), float)[sel], series="K-hat(t)",
                          estimator=name)
        if hasattr(est, "reflex_gain_at"):
            ctx.metric("reflex_kept", float(est.reflex_h is not None), name)
            if est.reflex_h is not None and g_true is not None:
                g_hat = est.reflex_gain_at(grid)
                ctx.metric("reflex_gain_rmse_pct", 100.0 * float(np.sqrt(np.mean((g_hat - g_true) ** 2)) /
                                                                 np.mean(g_true)), name)
                if ctx.seed == 0:
                    ctx.curve("reflex_gain", grid, g_hat, series="estimate", estimator=name)
        err = k_hat - k_true
        ctx.metric("kmap_rmse", float(np.sqrt(np.mean(err ** 2))), name)
        ctx.metric("kmap_rmse_pct", 100.0 * float(np.sqrt(np.mean(err ** 2)) / np.mean(k_true)), name)
        ctx.metric("kmap_mean_error_pct", 100.0 * float(np.mean(err) / np.mean(k_true)), name)
        ctx.metric("kmap_max_error", float(np.max(np.abs(err))), name)
        yhat = np.asarray(est.predict(trial.input), float)
        if np.all(np.isfinite(yhat[m])):
            ctx.metric("vaf_output", vaf(trial.output[m], yhat[m]), name)
        if ctx.seed == 0:
            ctx.curve("k_theta", grid, k_hat, series="estimate", estimator=name)
