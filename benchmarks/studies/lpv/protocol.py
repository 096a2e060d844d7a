"""Protocol of the lpv study: K(theta) from a single trial with a slow imposed movement.

``lpv.kmap``: one case is one movement (its frequency and range, from the sweep) of the part's experiment
(a joint whose stiffness depends on the angle, ``position_dependent``, moved by a ``moving`` perturbation)
and one seed. Two answers are scored against the true K(theta) (the joint model's own function) on a grid
over the central ``coverage`` of the range the slow movement visits:

* ``pv_irf``: the parameter-varying IRF scheduled on the slow angle, K(theta) with its band;
* ``fsewls`` mapped through theta: FSEWLS's K-hat(t) (the movement high-passed out, Xu & Hollerbach's
  frequency separation) on its valid, scored samples, regressed on the slow angle by a polynomial of the
  same degree as pv_irf's basis (``n_basis - 1``; its coefficients by least squares), the way a user of a
  time-varying method would read K(theta) from K(t).

Both methods are told the movement's speed, as the experimenter who imposed it knows it (never the
truth): the slow angle's cutoff (pv_irf's ``slow_cutoff``) and FSEWLS's high-pass edge are
``cutoff_factor`` times the movement's frequency, at least ``min_cutoff``.

Metrics (estimator ``pv_irf`` or ``fsewls``): ``kmap_rmse`` (N·m/rad) and ``kmap_rmse_pct`` (of the mean
true K over the grid), ``kmap_max_error``; pv_irf's ``band_coverage`` (fraction of grid points whose true K
lies in the band) and ``band_halfwidth`` (mean, N·m/rad); ``vaf_output`` and ``fit_time_s``. Case level:
``range_rad`` (the slow movement's span), ``speed_rad_s`` (its rms velocity). Curves for the figure (seed
0): K(theta) of the truth, each method and pv_irf's band.

References
----------
Sobhani Tehrani & Kearney (2022), the parameter-varying parallel cascade (K scheduled on the ankle's
position); Xu & Hollerbach (1998), FSEWLS (the frequency separation of a voluntary movement).
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


def _map_through(theta: np.ndarray, khat: np.ndarray, degree: int, grid: np.ndarray) -> np.ndarray:
    """K-hat(t) regressed on theta(t) by a polynomial of ``degree`` (least squares), read on ``grid``."""
    c = np.polynomial.polynomial.polyfit(theta, khat, degree)
    return np.polynomial.polynomial.polyval(grid, c)


@register("lpv.kmap", KmapParams)
def kmap(ctx: Context) -> None:
    """pv_irf's K(theta) and FSEWLS's K-hat(t) mapped through theta(t), against the truth (module docstring)."""
    p = ctx.params
    exp = with_movement(ctx.experiment, p)
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
    if ctx.seed == 0:
        ctx.curve("k_theta", grid, k_true, series="truth")
    for name, estimator in ctx.estimators.items():
        settings = estimator.settings
        if name == "pv_irf":
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
        err = k_hat - k_true
        ctx.metric("kmap_rmse", float(np.sqrt(np.mean(err ** 2))), name)
        ctx.metric("kmap_rmse_pct", 100.0 * float(np.sqrt(np.mean(err ** 2)) / np.mean(k_true)), name)
        ctx.metric("kmap_max_error", float(np.max(np.abs(err))), name)
        yhat = np.asarray(est.predict(trial.input), float)
        if np.all(np.isfinite(yhat[m])):
            ctx.metric("vaf_output", vaf(trial.output[m], yhat[m]), name)
        if ctx.seed == 0:
            ctx.curve("k_theta", grid, k_hat, series="estimate", estimator=name)
