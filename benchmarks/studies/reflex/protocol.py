"""Protocol of the reflex study: what an unmodelled stretch reflex does to every stiffness estimator, and how
well the parallel cascade separates it.

``reflex.bias``: one case is one joint (the part's experiment, with a reflex pathway), one reflex gain and
its time variation (the sweep), R realizations (``sims.simulate(experiment, seed, realization=r)``: every
random stream drawn anew, the joint's time variation kept). Every estimator of the part is fitted to each
realization (the ensemble methods to an ensemble of ``ensemble_size``: realizations ``r, r + R, ...``, as
the comparison protocol does) and scored against the simulated *intrinsic* stiffness (the static gain of
the true frozen intrinsic impedance, :func:`benchmarks.scoring.frozen_stiffness`), so that what the reflex
torque adds to an estimate is its bias. Metrics per estimator:

* ``bias_pct`` per realization and ``bias_mean_pct`` over them: the mean over the scored samples of
  ``(K-hat - K) / mean K`` in percent (the stiffness bias; the study's figure shows how it grows with the
  reflex); ``bias_rms``, ``random_error`` (:mod:`benchmarks.metrics`), ``vaf_stiffness`` (a time-varying
  K), ``vaf_output`` and ``fit_time_s``, as the comparison protocol records them;
* for the parallel cascades (estimates with ``vaf_reflex``): ``vaf_total``, ``vaf_intrinsic``, ``vaf_reflex``
  (the estimate's own VAFs of the measured torque), ``vaf_reflex_true`` (the true reflex torque's VAF of the
  measured torque, on the same samples), ``separation_intrinsic`` and ``separation_reflex`` (VAF of each
  predicted pathway torque against the true one), ``delay_error_samples`` and ``reflex_kept`` (1 or 0);
* ``not_fitted`` (value NaN, label ``reason``) when an estimator refuses the data.

Case level (estimator ``""``): ``reflex_share`` (the true reflex torque's VAF of the noise-free torque of
realization 0 over the scored samples) and ``reflex_gain_mean``. Mirbagheri et al. (2000) report reflex
contributions from about 1 % to "as high as 55 % in one case"; the study's checks keep every case's
``reflex_share`` in that range (``benchmarks/studies/reflex/study.yaml``, reading F2). A time-varying gain
makes the reflex a slow torque too (the gain times the rectified velocity's mean), which this share counts
with the rest: the check bounds every case's share, constant and time-varying.

References
----------
Kearney, Stein & Parameswaran (1997) (the reflex pathway and its separation); Mirbagheri, Barbeau &
Kearney, "Intrinsic and reflex contributions to human ankle stiffness: variation with activation level and
position", Exp. Brain Res. 135 (2000) 423-436, abstract (the range of reflex contributions); van de Ruit, Mugge,
Cavallo, Lataire, Ludvig & Schouten, "Quantitative comparison of time-varying system identification
methods to describe human joint impedance" (the bias and random-error metrics).
"""
from __future__ import annotations

import dataclasses
import math
from typing import Literal

import numpy as np

from jointbench import sims
from jointbench.benchmarks import metrics
from jointbench.core.scores import vaf
from jointbench.benchmarks.protocols import Context, register
from jointbench.benchmarks.compare.protocol import impedance
from jointbench.benchmarks.scoring import fit_timed, frozen_stiffness, scored_samples
from jointbench.core.ensemble import Ensemble, valid_mask
from jointbench.core.errors import InputError, Refused
from jointbench.core.schema import param
from jointbench.sims.profile import parse_profile


@dataclasses.dataclass(frozen=True)
class ReflexParams:
    """One reflex gain and its time variation (from the sweep), and how the case is run and scored."""

    gain: float = param(0.0, unit="N.m.s/rad", ge=0, doc="reflex gain G (the sweep): the constant gain, or the "
                                                          "sine's peak")
    variation: Literal["constant", "sine"] = param("constant", doc="the gain constant G, or a sine between 0 and G "
                                                                     "(at its peak as strong as the constant case)")
    gain_period: float = param(13.0, unit="s", gt=0, doc="period of the sine gain")
    realizations: int = param(3, ge=2, doc="R: realizations per case")
    ensemble_size: int = param(5, ge=2, doc="realizations in each ensemble of the ensemble methods")
    ensemble_methods: tuple[str, ...] = param(("sds", "guarin", "ensemble_irf", "tv_parallel_cascade"),
                                              doc="the estimators fitted to ensembles")
    discard: float = param(5.0, unit="s", ge=0, doc="seconds not scored at each end")
    curve_rate: float = param(5.0, unit="Hz", gt=0, doc="rate of the stored mean-stiffness curves")


def with_gain(exp, p: ReflexParams):
    """The experiment with the reflex gain of the case: ``G``, or ``G/2 + (G/2) sin(2 pi t / gain_period)``
    (from 0 to G: the time-varying reflex at its peak is the constant one of the same G, so that the
    constant sweep's range bounds both)."""
    if exp.reflex is None:
        raise ValueError("reflex.bias needs an experiment whose joint has a 'reflex' pathway")
    g = (p.gain if p.variation == "constant" or p.gain == 0 else
         {"shape": "sine", "mean": p.gain / 2, "amplitude": p.gain / 2, "period": p.gain_period})
    return dataclasses.replace(exp, reflex=dataclasses.replace(exp.reflex, gain=parse_profile(g, "gain")))


def _share(p: ReflexParams) -> tuple:
    return (p.gain, p.variation, p.gain_period)


@register("reflex.bias", ReflexParams, share=_share)
def bias(ctx: Context) -> None:
    """Every estimator on R realizations of one reflex gain (module docstring)."""
    p = ctx.params
    exp = with_gain(ctx.experiment, p)
    R, M = p.realizations, p.ensemble_size
    cache: dict[int, object] = {}

    def trial(r: int):
        if r not in cache:
            cache[r] = impedance(sims.simulate(exp, ctx.seed, realization=r, name=f"realization {r}"))
        return cache[r]

    first = trial(0)
    t = first.time
    k = frozen_stiffness(first)
    keep = scored_samples(t, p.discard)
    s = first.truth.signals
    ctx.metric("reflex_share", vaf(s["torque"][keep] - s["torque"][keep].mean(),
                                   s["reflex_torque"][keep] - s["reflex_torque"][keep].mean(), undefined="nan"))
    ctx.metric("reflex_gain_mean", float(np.mean(s["reflex_gain"][keep])))
    for name, estimator in ctx.estimators.items():
        khats, masks = [], []
        for r in range(R):
            data = trial(r)
            if name in p.ensemble_methods:
                data = Ensemble(tuple(trial(r + R * m) for m in range(M)), name=f"ensemble {r}")
            try:
                est, seconds = fit_timed(estimator, data)
            except Refused as exc:           # the output gate: this method refused, the others kept
                ctx.refused(name, exc, realization=r)
                break
            except InputError as exc:
                ctx.metric("not_fitted", math.nan, name, realization=r, reason=str(exc))
                break
            tr = trial(r)
            khat = np.asarray(est.stiffness(t), float)
            m = keep & valid_mask(est, t)
            khats.append(khat)
            masks.append(m)
            ctx.metric("fit_time_s", seconds, name, realization=r)
            ctx.metric("bias_pct", 100.0 * float(np.mean(khat[m] - k[m]) / np.mean(k[m])), name, realization=r)
            if np.ptp(k[m]) > 0:
                ctx.metric("vaf_stiffness", metrics.stiffness_vaf(k[m], khat[m]), name, realization=r)
            yhat = np.asarray(est.predict(tr.input), float)
            if np.all(np.isfinite(yhat[m])):
                ctx.metric("vaf_output", vaf(tr.output[m], yhat[m]), name, realization=r)
            if hasattr(est, "vaf_reflex"):
                _separation(ctx, name, est, tr, exp, r)
        if len(khats) < R:
            continue
        common = np.logical_and.reduce(masks)
        K = np.asarray(khats)[:, common]
        kc = k[common]
        b_rms, b_mean = metrics.bias(kc, K)
        ctx.metric("bias_mean_pct", 100.0 * b_mean / float(np.mean(kc)), name)
        ctx.metric("bias_rms", b_rms, name)
        ctx.metric("random_error", metrics.random_error(K), name)
        if ctx.seed == 0:
            step = max(1, int(round(first.fs / p.curve_rate)))
            sel = np.flatnonzero(common)[::step]
            ctx.curve("stiffness", t[sel], K.mean(axis=0)[::step], series="mean estimate", estimator=name)
            ctx.curve("stiffness", t[sel], k[sel], series="truth", estimator=name)


def _separation(ctx: Context, name: str, est, tr, exp, r: int) -> None:
    """The parallel cascade's own VAFs and its separation of the two pathways against the truth."""
    s = tr.truth.signals
    u = tr.input - tr.input.mean()
    rows = getattr(est, "rows", None)
    used = np.zeros(tr.n, bool)
    if rows is not None:
        used[rows[0]:rows[1]] = True
    else:
        used = np.asarray(est.valid, bool).copy()
    y = tr.output - tr.output.mean()
    Tr = s["reflex_torque"] - s["reflex_torque"][used].mean()
    Ti = s["intrinsic_torque"] - s["intrinsic_torque"][used].mean()
    for metric, value in (("vaf_total", est.vaf_total), ("vaf_intrinsic", est.vaf_intrinsic),
                          ("vaf_reflex", est.vaf_reflex)):
        ctx.metric(metric, value, name, realization=r)
    ctx.metric("vaf_reflex_true", vaf(y[used], Tr[used], undefined="nan"), name, realization=r)
    ti = est.intrinsic_torque(u) if hasattr(est, "intrinsic_torque") else est.predict(u)
    ctx.metric("separation_intrinsic", vaf(Ti[used], ti[used] - ti[used].mean(), undefined="nan"), name,
               realization=r)
    kept = est.reflex_h is not None
    ctx.metric("reflex_kept", float(kept), name, realization=r)
    if kept:
        tr_hat = est.reflex_torque(u)
        if np.var(Tr[used]) > 0:
            ctx.metric("separation_reflex", vaf(Tr[used], tr_hat[used] - tr_hat[used].mean(), undefined="nan"), name,
                       realization=r)
        ctx.metric("delay_error_samples", float(est.reflex_delay) - exp.reflex.delay * tr.fs, name, realization=r)
