"""The comparison protocol: one estimator on one scenario, R realizations, scored against the truth.

A case of a comparison grid (:mod:`jointbench.benchmarks.compare.grid`) names one estimator and a fully resolved
experiment (scenario, joint, time variation, perturbation, noise, rate, backend). It simulates R realizations
(``sims.simulate(experiment, seed, realization=r)``: every random stream drawn anew, the joint's time
variation kept), fits the estimator to each (to a single trial, or to an ensemble of ``ensemble_size``
realizations: realizations ``r, r + R, r + 2R, ...``), and scores every estimate against the simulated
stiffness with the metrics of the comparison framework (:mod:`benchmarks.metrics`, studies.md D):

* per realization (label ``realization``): ``vaf_stiffness``, ``vaf_output`` (the prediction of the
  fitted trial's measured output from its input), ``fit_time_s`` (wall time of the fit), ``error_rms``
  (RMS of ``k_hat_r - k`` over the samples scored in every realization: ``total_error`` is the RMS of these);
  realization r is the same data for every method (same seed and index), so these rows pair across methods;
* over the R realizations: ``bias_rms``, ``bias_mean``, ``random_error``, ``total_error`` and, for a
  square-wave stiffness, ``rise_time_s`` (mean over the steps) with ``n_steps``; each with its spread
  ``p05``/``p95``, a 90 % percentile bootstrap interval over ``spread_draws`` resamplings of the R
  realizations re-centred on the estimate (:func:`recentred_percentile_interval`; drawn from the case's seeded
  generator), which contains the value;
* ``not_fitted`` (value NaN, label ``reason``) when the estimator refuses the data (an InputError).

Every row carries ``settings`` (JSON of the estimator's settings as fitted). With ``tuning: tuned`` the
settings are first chosen (:func:`select_setting`) among ``search`` (full settings mappings, from the grid's
``tuning`` search) by the output VAF on tuning realizations (indices from :data:`TUNE_OFFSET`, never
scored; their truth removed before anything sees them): fitted on one tuning trial (or an ensemble of
``ensemble_size`` tuning realizations), each candidate predicts the torque of two other tuning realizations
from their angle (score: the mean VAF). Rows ``tuning_vaf_output`` (label ``candidate``, ``chosen``) give
every candidate's score; every row of a tuned case carries ``tuning_edge``: ``inside``, or the settings whose
chosen value is the lowest or highest of the candidates scored (``forgetting=highest``: the candidates, not
the method, bounded the choice; :func:`edge_of`). The search is the study's ``tuning`` for the estimator, or
what the estimator's settings declare (:func:`jointbench.benchmarks.compare.tuning.search_for`).

Protocol ``identifiability`` (estimator ``(scenario)``, one case per resolved experiment unless the part's
``params.identify`` is false): the figures of
:mod:`jointbench.benchmarks.compare.identifiability` from the truth, median over the first ``min(R, 3)`` realizations.

Every method is given the impedance direction, angle to torque (:func:`impedance`), and ``vaf_output``
is the VAF of the torque predicted from the angle. The simulated stiffness is the static gain of the
true frozen impedance at every sample:
``K(t)`` for a joint on its own, ``k(t)`` in series with the hand contact for the wrist (about
``k - k^2/k_c``), the gain every estimator's ``stiffness(t)`` estimates. The scored samples lie
``discard`` seconds from both ends, where the estimate is valid (:func:`jointbench.core.ensemble.valid_mask`),
in every realization.

References
----------
van de Ruit, Mugge, Cavallo, Lataire, Ludvig & Schouten, "Quantitative comparison of time-varying system
identification methods to describe human joint impedance" (metrics 1-5); ../shared/specs/studies.md D.
"""
from __future__ import annotations

import dataclasses
import json
import math
from typing import Any, Literal

import numpy as np

from jointbench import estimators, sims
from jointbench.benchmarks import metrics
from jointbench.core.scores import vaf
from jointbench.benchmarks.compare.identifiability import FIGURES, trial_identifiability, without_torque_noise
from jointbench.benchmarks.compare import oracle
from jointbench.benchmarks.protocols import Context, register
from jointbench.benchmarks.scoring import fit_timed, frozen_stiffness, scored_samples
from jointbench.core.ensemble import Ensemble, valid_mask
from jointbench.core.errors import InputError, Refused
from jointbench.core.schema import param
from jointbench.fitting.pipeline import impedance  # the one definition (lpv and reflex import it from here)


TUNE_OFFSET = 100_000
#: held-out tuning realizations each candidate predicts (its score: the mean output VAF)
N_HELD_OUT = 2
#: realizations whose identifiability figures are computed (median)
N_IDENTIFY = 3
#: the estimator label of the identifiability rows
SCENARIO_ROW = "(scenario)"


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
    tuning: Literal["paper", "tuned"] = param("paper", doc="label: the paper's settings, or tuned on tuning "
                                                           "realizations (never scored) among 'search'")
    identify: bool = param(True, doc="the grid adds one identifiability case per resolved experiment (false: none)")
    search: Any = param(None, doc="tuned: the candidate settings (full mappings; the grid's tuning search)")
    estimator: str = param("", doc="label: the estimator of the case (its settings: the case's estimators)")
    scenario: str = param("", doc="label: the scenario")
    joint: str = param("", doc="label: the joint model")
    variation: str = param("", doc="label: the time variation of the stiffness")
    perturbation: str = param("", doc="label: the perturbation")
    noise: Any = param(None, doc="label: var(noise)/var(torque) of the torque channel")
    fs: Any = param(None, doc="label: the acquired rate")
    backend: str = param("", doc="label: the simulation backend")


def recentred_percentile_interval(value: float, draws, floor: float | None = 0.0) -> tuple[float, float]:
    """The 90 % percentile bootstrap interval of ``value`` re-centred on it: the 5th and 95th percentiles
    (nearest ranks outward) of ``draws - (median(draws) - value)``, not below ``floor`` (the metrics are
    >= 0; ``None`` for the signed mean bias).

    The re-centring removes the bootstrap's own bias (an RMS of a mean over resampled realizations is
    inflated by the random error, so the raw percentiles can lie above the estimate); the interval keeps
    the shape of the bootstrap distribution and contains ``value``. An infinite value (a step never
    followed) gives ``(value, value)``; infinite draws (resamplings in which a step is never followed) are
    shifted by the median of the finite ones, so the upper end may be infinite.
    """
    x = np.asarray(draws, float)
    if not np.isfinite(value):
        return float(value), float(value)
    finite = x[np.isfinite(x)]
    if len(finite) == 0:
        return float(value), math.inf
    shift = float(np.median(finite)) - value
    y = x - shift
    lo, hi = float(np.percentile(y, 5, method="lower")), float(np.percentile(y, 95, method="higher"))
    lo, hi = min(lo, value), max(hi, value)   # only moves an end where half the draws or more are infinite
    if floor is not None:
        lo, hi = max(lo, floor), max(hi, floor)
    return lo, hi


def settings_json(estimator) -> str:
    """The estimator's settings as fitted, JSON with sorted keys (the ``settings`` column)."""
    return json.dumps(dataclasses.asdict(estimator.settings), sort_keys=True, default=str)


def select_setting(make, candidates, fit_data, held_out, keep) -> tuple[int, list[float]]:
    """The candidate whose estimate, fitted to ``fit_data``, best predicts the output of the ``held_out``
    trials from their input (mean VAF over the ``keep`` samples valid for the estimate): ``(index, scores)``,
    score NaN where the candidate cannot be fitted. ``make(candidate)`` builds the estimator. Only the tuning
    data are given: this function cannot see a scored realization or the truth (the caller removes it)."""
    scores = []
    for cand in candidates:
        try:
            est = make(cand).fit(fit_data)
        except InputError:
            scores.append(math.nan)
            continue
        vafs = []
        for trial in held_out:
            m = keep & valid_mask(est, trial.time)
            yhat = np.asarray(est.predict(trial.input), float)
            ok = m.sum() >= 2 and bool(np.all(np.isfinite(yhat[m])))
            vafs.append(vaf(trial.output[m], yhat[m]) if ok else math.nan)
        scores.append(float(np.mean(vafs)))
    if not np.any(np.isfinite(scores)):
        raise InputError("no candidate setting could be fitted to the tuning realizations")
    return int(np.nanargmax(scores)), scores


#: the ``tuning_edge`` label of a tuned case whose choice lies inside the candidates of every setting
INSIDE = "inside"


def _finite_number(v) -> bool:
    return isinstance(v, (int, float, np.number)) and not isinstance(v, bool) and bool(np.isfinite(v))


def edge_of(name: str, candidates, chosen: int, scores) -> str:
    """Where candidate ``chosen`` of estimator ``name`` lies among the ``candidates`` scored (a finite
    score), for each setting they vary over with numeric values: ``"<setting>=lowest"`` or
    ``"<setting>=highest"`` (joined by ``"; "``) when it takes the lowest or highest value tried, else
    :data:`INSIDE`. A choice on an edge means the candidates, not the method, bounded the result: a value
    beyond them may predict better."""
    parsed = [dataclasses.asdict(estimators.make(name, c, f"tuning of {name}").settings) for c in candidates]
    scored = [s for s, score in zip(parsed, scores) if _finite_number(score)]
    mine = parsed[chosen]
    out = []
    for key, value in mine.items():
        values = {s[key] for s in scored if _finite_number(s[key])}
        if len(values) < 2 or not _finite_number(value):
            continue
        if value == min(values):
            out.append(f"{key}=lowest")
        elif value == max(values):
            out.append(f"{key}=highest")
    return "; ".join(out) or INSIDE


def _blind_copy(trial):
    return trial.replace(truth=None)


def tuning_data(ctx, p: CompareParams):
    """The tuning data of a case (realizations from :data:`TUNE_OFFSET`, truth removed): what is fitted (a
    trial, or an ensemble of ``ensemble_size``) and the :data:`N_HELD_OUT` held-out trials it predicts."""
    def sim(i):
        return _blind_copy(impedance(sims.simulate(ctx.experiment, ctx.seed, realization=TUNE_OFFSET + i,
                                                   name=f"tuning realization {i}")))
    n = p.ensemble_size if p.data == "ensemble" else 1
    fit = [sim(i) for i in range(n)]
    data = Ensemble(tuple(fit), name="tuning ensemble") if p.data == "ensemble" else fit[0]
    return data, [sim(n + j) for j in range(N_HELD_OUT)]


def _share(p: CompareParams) -> tuple:
    """Every case of one resolved experiment, seed and backend shares the responses (sims.reuse)."""
    return ()


def _tune(ctx, p: CompareParams, name: str, keep: np.ndarray):
    """The tuned estimator of a case, the rows of its search and where its choice lies among the candidates
    (:func:`edge_of`: the ``tuning_edge`` label)."""
    if not p.search:
        raise ValueError(f"tuning: tuned needs the candidate settings ('search') of {name}")
    if p.realizations * p.ensemble_size > TUNE_OFFSET:
        raise ValueError(f"realizations x ensemble_size reaches the tuning realizations ({TUNE_OFFSET})")
    fit, held = tuning_data(ctx, p)
    best, scores = select_setting(lambda c: estimators.make(name, c, f"tuning of {name}"), p.search, fit, held, keep)
    rows = [dict(candidate=json.dumps(c, sort_keys=True, default=str), chosen=i == best, value=v)
            for i, (c, v) in enumerate(zip(p.search, scores))]
    return estimators.make(name, p.search[best], f"tuning of {name}"), rows, edge_of(name, p.search, best, scores)


def _realization(ctx, p: CompareParams, r: int, first):
    """Realization ``r`` as every method is given it (:func:`impedance`) and what is fitted: the trial, or the
    ensemble of realizations ``r, r + R, r + 2R, ...`` (``first``: realization 0, already simulated)."""
    R, M = p.realizations, p.ensemble_size
    trial = impedance(first if r == 0 else sims.simulate(ctx.experiment, ctx.seed, realization=r,
                                                         name=f"realization {r}"))
    data = trial
    if p.data == "ensemble":
        data = Ensemble((trial, *(impedance(sims.simulate(ctx.experiment, ctx.seed, realization=r + R * m,
                                                          name=f"realization {r + R * m}")) for m in range(1, M))),
                        name=f"ensemble {r}")
    return trial, data


def _fit_realizations(ctx, p: CompareParams, name: str, estimator, first, k: np.ndarray, keep: np.ndarray,
                      label: dict) -> tuple[list, list] | None:
    """Fit every realization and record its metrics (``fit_time_s``, ``vaf_stiffness``, ``vaf_output``): the
    estimated stiffness and the valid scored samples of each, or None when the estimator refuses the data
    (recorded as ``not_fitted``, with the reason)."""
    t = first.time
    khats, masks = [], []
    for r in range(p.realizations):
        trial, data = _realization(ctx, p, r, first)
        try:
            est, seconds = fit_timed(estimator, data)
        except Refused as exc:               # the output gate: this method refused, the others kept
            ctx.refused(name, exc, realization=r, **label)
            return None
        except InputError as exc:            # the data cannot support this estimator: a reason, not a crash
            ctx.metric("not_fitted", math.nan, name, realization=r, reason=str(exc), **label)
            return None
        khat = np.asarray(est.stiffness(t), float)
        m = keep & valid_mask(est, t)
        khats.append(khat)
        masks.append(m)
        ctx.metric("fit_time_s", seconds, name, realization=r, **label)
        if m.sum() >= 2 and np.ptp(k[m]) > 0:
            ctx.metric("vaf_stiffness", metrics.stiffness_vaf(k[m], khat[m]), name, realization=r, **label)
        yhat = np.asarray(est.predict(trial.input), float)
        if m.sum() >= 2 and np.all(np.isfinite(yhat[m])):
            ctx.metric("vaf_output", vaf(trial.output[m], yhat[m]), name, realization=r, **label)
    return khats, masks


def _framework(tc: np.ndarray, kc: np.ndarray, K: np.ndarray, square: bool) -> dict[str, float]:
    """The metrics over realizations of the estimates ``K`` (realization x sample) of ``kc`` at times ``tc``;
    with ``square`` (a square-wave stiffness) the rise time too."""
    b_rms, b_mean = metrics.bias(kc, K)
    out = {"bias_rms": b_rms, "bias_mean": b_mean, "random_error": metrics.random_error(K),
           "total_error": metrics.total_error(kc, K)}
    if square:
        out["rise_time_s"] = metrics.rise_time(tc, kc, K.mean(axis=0))[0]
    return out


def _score_realizations(ctx, p: CompareParams, name: str, tc: np.ndarray, kc: np.ndarray, K: np.ndarray,
                        label: dict) -> None:
    """Record ``error_rms`` of each realization, then the metrics over realizations (:func:`_framework`) with
    their spread over ``spread_draws`` bootstrap resamplings of the realizations
    (:func:`recentred_percentile_interval`)."""
    R = p.realizations
    for r in range(R):
        ctx.metric("error_rms", float(np.sqrt(np.mean((K[r] - kc) ** 2))), name, realization=r, **label)
    square = len(metrics.steps(kc)) > 0
    values = _framework(tc, kc, K, square)
    draws = [_framework(tc, kc, K[ctx.rng.integers(0, R, R)], square) for _ in range(p.spread_draws)]
    for metric, v in values.items():
        spread = {}
        if draws:
            spread = dict(zip(("p05", "p95"), recentred_percentile_interval(
                v, [d[metric] for d in draws], None if metric == "bias_mean" else 0.0)))
        extra = {"n_steps": int(len(metrics.steps(kc)))} if metric == "rise_time_s" else {}
        ctx.metric(metric, v, name, n=R, **spread, **extra, **label)


def _record_curves(ctx, p: CompareParams, name: str, first, k: np.ndarray, K: np.ndarray,
                   common: np.ndarray) -> None:
    """The mean estimate, its 5th and 95th percentiles over realizations and the truth at ``curve_rate``, for
    the figures."""
    t = first.time
    step = max(1, int(round(first.fs / p.curve_rate)))
    sel = np.flatnonzero(common)[::step]
    ctx.curve("stiffness", t[sel], K.mean(axis=0)[::step], series="mean estimate", estimator=name,
              tuning=p.tuning)
    ctx.curve("stiffness", t[sel], np.percentile(K, 5, axis=0)[::step], series="p05 over realizations",
              estimator=name, tuning=p.tuning)
    ctx.curve("stiffness", t[sel], np.percentile(K, 95, axis=0)[::step], series="p95 over realizations",
              estimator=name, tuning=p.tuning)
    ctx.curve("stiffness", t[sel], k[sel], series="truth", estimator=name, tuning=p.tuning)


@register("compare", CompareParams, tags=("generic",), share=_share)
def compare(ctx: Context) -> None:
    """One estimator on one resolved experiment: R realizations fitted and scored (module docstring)."""
    p = ctx.params
    if len(ctx.estimators) != 1:
        raise ValueError(f"a comparison case fits one estimator, got {len(ctx.estimators)}")
    (name, estimator), = ctx.estimators.items()
    first = sims.simulate(ctx.experiment, ctx.seed, name="realization 0")
    t = first.time
    k = frozen_stiffness(first)
    keep = scored_samples(t, p.discard)
    if keep.sum() < 2:
        raise ValueError(f"discard: {p.discard:g} s at each end leaves nothing of the {t[-1] - t[0]:.3g} s record")
    search_rows, label = [], {}
    if p.tuning == "tuned":
        try:
            estimator, search_rows, label["tuning_edge"] = _tune(ctx, p, name, keep)
        except InputError as exc:
            ctx.metric("not_fitted", math.nan, name, reason=f"tuning: {exc}")
            return
    label["settings"] = settings_json(estimator)
    for row in search_rows:
        ctx.metric("tuning_vaf_output", row.pop("value"), name, **label, **row)
    fitted = _fit_realizations(ctx, p, name, estimator, first, k, keep, label)
    if fitted is None:
        return
    common = np.logical_and.reduce(fitted[1])
    if common.sum() < 2:
        ctx.metric("not_scored", math.nan, name, reason="no sample is valid in every realization", **label)
        return
    K = np.asarray(fitted[0])[:, common]
    _score_realizations(ctx, p, name, t[common], k[common], K, label)
    if ctx.seed == 0:                       # the mean estimate and the truth, for the figures
        _record_curves(ctx, p, name, first, k, K, common)


@register("identifiability", CompareParams, tags=("generic",), share=_share)
def identify(ctx: Context) -> None:
    """The identifiability figures of one resolved experiment (module docstring), from the truth."""
    p = ctx.params
    clean_exp = without_torque_noise(ctx.experiment)
    n = min(p.realizations, N_IDENTIFY)
    figs = []
    for r in range(n):
        trial = sims.simulate(ctx.experiment, ctx.seed, realization=r, name=f"realization {r}")
        clean = sims.simulate(clean_exp, ctx.seed, realization=r, name=f"realization {r} (no noise)")
        keep = scored_samples(trial.time, p.discard)
        figs.append(trial_identifiability(trial, clean, frozen_stiffness(trial), keep))
    for f in FIGURES:
        ctx.metric(f, float(np.median([d[f] for d in figs])), SCENARIO_ROW, n=n)
    # the oracle bound (benchmarks/compare/oracle.py): on single trials, and on ensembles where they run
    if not oracle.not_applicable(ctx.experiment):
        ens = p.ensemble_size if oracle.fits_ensembles(p.backend) else 0
        for metric, value in oracle.oracle_errors(ctx.experiment, ctx.seed, p.realizations, p.discard, ens).items():
            ctx.metric(metric, value, SCENARIO_ROW, n=p.realizations)
