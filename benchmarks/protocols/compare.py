"""The comparison protocol: one estimator on one scenario, R realizations, scored against the truth.

A case of a comparison grid (:mod:`benchmarks.grid`) names one estimator and a fully resolved experiment
(scenario, joint, time variation, perturbation, noise, rate, backend). It simulates R realizations
(``sims.simulate(experiment, seed, realization=r)``: every random stream drawn anew, the joint's time
variation kept), fits the estimator to each (to a single trial, or to an ensemble of ``ensemble_size``
realizations: realizations ``r, r + R, r + 2R, ...``), and scores every estimate against the simulated
stiffness with the metrics of the comparison framework (:mod:`benchmarks.metrics`, studies.md D):

* per realization (label ``realization``): ``vaf_stiffness``, ``vaf_output`` (the prediction of the
  fitted trial's measured output from its input), ``fit_time_s`` (wall time of the fit);
* over the R realizations: ``bias_rms``, ``bias_mean``, ``random_error``, ``total_error`` and, for a
  square-wave stiffness, ``rise_time_s`` (mean over the steps) with ``n_steps``; each with its spread
  ``p05``/``p95``, the basic bootstrap 90 % interval over ``spread_draws`` resamplings of the R realizations
  (:func:`basic_interval`; drawn from the case's seeded generator);
* ``not_fitted`` (value NaN, label ``reason``) when the estimator refuses the data (an InputError).

Every method is given the impedance direction, angle to torque (:func:`impedance`), and ``vaf_output``
is the VAF of the torque predicted from the angle. The simulated stiffness is the static gain of the
true frozen impedance at every sample:
``K(t)`` for a joint on its own, ``k(t)`` in series with the hand contact for the wrist (about
``k - k^2/k_c``), the gain every estimator's ``stiffness(t)`` estimates. The scored samples lie
``discard`` seconds from both ends, where the estimate is valid (:func:`jointbench.ensemble.valid_mask`),
in every realization.

References
----------
van de Ruit, Mugge, Cavallo, Lataire, Ludvig & Schouten, "Quantitative comparison of time-varying system
identification methods to describe human joint impedance" (metrics 1-5); ../shared/specs/studies.md D.
"""
from __future__ import annotations

import dataclasses
import math
from typing import Any, Literal

import numpy as np

from jointbench import sims
from jointbench.benchmarks import metrics
from jointbench.benchmarks.protocols import Context, register
from jointbench.benchmarks.scoring import fit_timed, frozen_stiffness, scored_samples
from jointbench.ensemble import Ensemble, valid_mask
from jointbench.errors import InputError
from jointbench.schema import param


@dataclasses.dataclass(frozen=True)
class CompareParams:
    """How a grid case is run and scored; the labels name the grid values of the case."""

    realizations: int = param(10, ge=2, doc="R: realizations per case (independent seeds of every stream)")
    ensemble_size: int = param(5, ge=2, doc="realizations in each ensemble (data: ensemble)")
    discard: float = param(5.0, unit="s", ge=0, doc="seconds not scored at each end of the record")
    curve_rate: float = param(10.0, unit="Hz", gt=0, doc="rate of the stored mean-stiffness curves (figures)")
    spread_draws: int = param(200, ge=0, doc="bootstrap draws over the realizations for the spread (p05, p95) "
                                             "of the metrics over realizations; 0 = none")
    data: Literal["trial", "ensemble"] = param("trial", doc="fit single trials or ensembles")
    estimator: str = param("", doc="label: the estimator of the case (its settings: the case's estimators)")
    scenario: str = param("", doc="label: the scenario")
    joint: str = param("", doc="label: the joint model")
    variation: str = param("", doc="label: the time variation of the stiffness")
    perturbation: str = param("", doc="label: the perturbation")
    noise: Any = param(None, doc="label: var(noise)/var(torque) of the torque channel")
    fs: Any = param(None, doc="label: the acquired rate")
    backend: str = param("", doc="label: the simulation backend")


def basic_interval(value: float, draws, floor: float | None = 0.0) -> tuple[float, float]:
    """The basic (reverse-percentile) bootstrap 90 % interval of ``value``: ``(2 v - q95, 2 v - q05)`` with
    the 5th and 95th percentiles of the ``draws`` (nearest ranks outward), not below ``floor`` (the metrics
    are >= 0; ``None`` for the signed mean bias). Unlike the percentile interval it contains the estimate
    even when resampling shifts the metric (an RMS of a mean over resampled realizations is biased upward
    by the random error); an infinite value (a step never followed) stays infinite."""
    x = np.asarray(draws, float)
    if not np.isfinite(value):
        return float(value), float(value)
    q05, q95 = np.percentile(x, 5, method="lower"), np.percentile(x, 95, method="higher")
    lo, hi = 2 * value - q95, 2 * value - q05
    if floor is not None:
        lo, hi = max(lo, floor), max(hi, floor)
    return float(lo), float(hi)


def impedance(trial):
    """The trial as every method is given it: the impedance, angle to torque (``imposed='angle'``), also
    when the apparatus imposed the torque (Xu's torque drive): the direction every method's stiffness and
    prediction refer to (FSEWLS fits torque from angle whatever was imposed; Westwick & Perreault's
    two-sided IRFs exist to identify the impedance of torque-driven joints)."""
    return trial if trial.imposed == "angle" else trial.replace(imposed="angle")


def _share(p: CompareParams) -> tuple:
    """Every case of one resolved experiment, seed and backend shares the responses (sims.reuse)."""
    return ()


@register("compare", CompareParams, tags=("generic",), share=_share)
def compare(ctx: Context) -> None:
    """One estimator on one resolved experiment: R realizations fitted and scored (module docstring)."""
    p = ctx.params
    if len(ctx.estimators) != 1:
        raise ValueError(f"a comparison case fits one estimator, got {len(ctx.estimators)}")
    (name, estimator), = ctx.estimators.items()
    R, M = p.realizations, p.ensemble_size
    first = sims.simulate(ctx.experiment, ctx.seed, name="realization 0")
    t = first.time
    k = frozen_stiffness(first)
    keep = scored_samples(t, p.discard)
    if keep.sum() < 2:
        raise ValueError(f"discard: {p.discard:g} s at each end leaves nothing of the {t[-1] - t[0]:.3g} s record")
    khats, masks = [], []
    for r in range(R):
        trial = impedance(first if r == 0 else sims.simulate(ctx.experiment, ctx.seed, realization=r,
                                                             name=f"realization {r}"))
        data = trial
        if p.data == "ensemble":
            data = Ensemble((trial, *(impedance(sims.simulate(ctx.experiment, ctx.seed, realization=r + R * m,
                                                              name=f"realization {r + R * m}")) for m in range(1, M))),
                            name=f"ensemble {r}")
        try:
            est, seconds = fit_timed(estimator, data)
        except InputError as exc:            # the data cannot support this estimator: a reason, not a crash
            ctx.metric("not_fitted", math.nan, name, realization=r, reason=str(exc))
            return
        khat = np.asarray(est.stiffness(t), float)
        m = keep & valid_mask(est, t)
        khats.append(khat)
        masks.append(m)
        ctx.metric("fit_time_s", seconds, name, realization=r)
        if m.sum() >= 2 and np.ptp(k[m]) > 0:
            ctx.metric("vaf_stiffness", metrics.stiffness_vaf(k[m], khat[m]), name, realization=r)
        yhat = np.asarray(est.predict(trial.input), float)
        if m.sum() >= 2 and np.all(np.isfinite(yhat[m])):
            ctx.metric("vaf_output", metrics.vaf(trial.output[m], yhat[m]), name, realization=r)
    common = np.logical_and.reduce(masks)
    if common.sum() < 2:
        ctx.metric("not_scored", math.nan, name, reason="no sample is valid in every realization")
        return
    K = np.asarray(khats)[:, common]
    kc, tc = k[common], t[common]
    square = len(metrics.steps(kc)) > 0

    def framework(K: np.ndarray) -> dict[str, float]:
        b_rms, b_mean = metrics.bias(kc, K)
        out = {"bias_rms": b_rms, "bias_mean": b_mean, "random_error": metrics.random_error(K),
               "total_error": metrics.total_error(kc, K)}
        if square:
            out["rise_time_s"] = metrics.rise_time(tc, kc, K.mean(axis=0))[0]
        return out

    values = framework(K)
    draws = [framework(K[ctx.rng.integers(0, R, R)]) for _ in range(p.spread_draws)]
    for metric, v in values.items():
        spread = {}
        if draws:
            spread = dict(zip(("p05", "p95"), basic_interval(v, [d[metric] for d in draws],
                                                              None if metric == "bias_mean" else 0.0)))
        extra = {"n_steps": int(len(metrics.steps(kc)))} if metric == "rise_time_s" else {}
        ctx.metric(metric, v, name, **spread, **extra)
    if ctx.seed == 0:                       # the mean estimate and the truth, for the figures
        step = max(1, int(round(first.fs / p.curve_rate)))
        sel = np.flatnonzero(common)[::step]
        ctx.curve("stiffness", t[sel], K.mean(axis=0)[::step], series="mean estimate", estimator=name)
        ctx.curve("stiffness", t[sel], k[sel], series="truth", estimator=name)
