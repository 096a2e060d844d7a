"""Generic protocol: simulate a trial, fit every listed estimator, score it against the truth."""
from __future__ import annotations

import dataclasses

import numpy as np

from jointbench import sims
from jointbench.benchmarks.metrics import relative_error
from jointbench.core.scores import vaf
from jointbench.benchmarks.protocols import Context, register
from jointbench.benchmarks.scoring import fit_gated
from jointbench.core.errors import Refused
from jointbench.core.estimate import FRFEstimate, IRFEstimate, ParametricEstimate
from jointbench.core.schema import param


@dataclasses.dataclass(frozen=True)
class FitParams:
    """The experiment and estimators say it all; ``near_unity`` only labels the coherence band recorded."""

    near_unity: float = param(0.9, gt=0, lt=1, doc="the squared coherence counts as near unity above this")


def coherence_band(f: np.ndarray, coherence: np.ndarray, level: float) -> tuple[float, float]:
    """Lowest and highest frequency (Hz) of the contiguous band around the coherence's maximum where it is
    at least ``level`` (NaN, NaN when it never is)."""
    f, c = np.asarray(f, float), np.asarray(coherence, float)
    if not np.any(c >= level):
        return float("nan"), float("nan")
    i = int(np.argmax(c))
    lo = i
    while lo > 0 and c[lo - 1] >= level:
        lo -= 1
    hi = i
    while hi < len(c) - 1 and c[hi + 1] >= level:
        hi += 1
    return float(f[lo]), float(f[hi])


def record_estimate_curves(ctx: Context, name: str, est, trial) -> None:
    """Curves of a nonparametric basis (FRF or IRF) and of the fitted model, for the figures."""
    basis = est.basis if isinstance(est, ParametricEstimate) else est
    if isinstance(basis, FRFEstimate):
        keep = basis.freq > 0
        f = basis.freq[keep]
        ctx.curve("frf_mag", f, np.abs(basis.H[keep]), series="estimate", estimator=name)
        ctx.curve("frf_phase", f, np.degrees(np.angle(basis.H[keep])), series="estimate", estimator=name)
        ctx.curve("coherence2", f, basis.coherence[keep], series="estimate", estimator=name)
        if isinstance(est, ParametricEstimate):
            model = est.frequency_response(f)
            ctx.curve("frf_mag", f, np.abs(model), series="model", estimator=name)
            ctx.curve("frf_phase", f, np.degrees(np.angle(model)), series="model", estimator=name)
        truth = trial.truth
        if truth is not None and np.ndim(truth.K) == 0:
            w = 2 * np.pi * f
            true = truth.K + 1j * w * truth.B - truth.I * w ** 2
            ctx.curve("frf_mag", f, np.abs(true), series="truth", estimator=name)
            ctx.curve("frf_phase", f, np.degrees(np.angle(true)), series="truth", estimator=name)
    elif isinstance(basis, IRFEstimate):
        ctx.curve("irf", basis.lags / basis.fs, basis.h, series="estimate", estimator=name)


@register("parametric_fit", FitParams, tags=("generic",))
def parametric_fit(ctx: Context) -> None:
    """Simulate ``ctx.experiment`` and score each estimator's I, B, K and torque prediction.

    Metrics per estimator: ``I``, ``B``, ``K`` (estimates), ``I_err_pct`` ... (signed relative error
    against the time-averaged truth), ``vaf_torque`` (percent VAF of the predicted torque against the
    measured torque, means removed).
    """
    trial = sims.simulate(ctx.experiment, ctx.seed)
    truth = trial.truth
    u = trial.angle - trial.angle.mean()
    y = trial.torque - trial.torque.mean()
    for name, estimator in ctx.estimators.items():
        try:
            est = fit_gated(estimator, trial)
        except Refused as exc:              # the output gate: this estimator refused, the others kept
            ctx.refused(name, exc)
            continue
        params = est.parameters()
        for p, values in params.items():
            value = float(np.mean(values))
            ctx.metric(p, value, name)
            if truth is not None:
                ctx.metric(f"{p}_err_pct", relative_error(float(np.mean(getattr(truth, p))), value), name)
        ctx.metric("stiffness", float(np.mean(est.stiffness(trial.time))), name)
        ctx.metric("vaf_torque", vaf(y, est.predict(u)), name)
        basis = est.basis if isinstance(est, ParametricEstimate) else est
        if isinstance(basis, FRFEstimate) and basis.coherence is not None:
            lo, hi = coherence_band(basis.freq, basis.coherence, ctx.params.near_unity)
            ctx.metric("coherence_band_low_hz", lo, name)
            ctx.metric("coherence_band_high_hz", hi, name)
        record_estimate_curves(ctx, name, est, trial)
