"""Protocol of the realdata study: every estimator on a recorded trial, scored by two-fold cross-validated output
VAF (no truth).

``realdata.crossval``: one case is one recorded trial (the sweep's ``trial``, an array of the data file). The
trial, at its recorded rate, is cut into two halves of equal length; each half is prepared as ``jointbench
estimate`` prepares a record (:func:`jointbench.fitting.pipeline.prepare`: the torque's sign, decimation by
``decimate`` with ``decimate_filter``). Fold 1 fits on the first half and predicts the torque of the second;
fold 2 the reverse. The prediction is the estimate's own (:meth:`Estimate.prediction` through
:func:`jointbench.fitting.pipeline.score`), so each method is scored on the samples and band its prediction
defines. Metrics per estimator and fold: ``vaf_cv`` (held-out half), ``vaf_fit`` (the half it was fitted on,
from the output gate), ``fit_time_s``; per estimator ``vaf_cv_mean`` over the two folds. An estimator that takes
no single trial (its ``accepts``) is ``skipped`` with the reason; a fit the output gate refuses is ``refused``;
one the estimator cannot make on these data (e.g. a multisine method on a random perturbation) is
``not_fitted`` with its one-line reason; an estimate whose prediction of the held-out half is that of the half it
was fitted on (its ``prediction`` ignores the record given: FSEWLS's, which scores its stored filtered torque) is
``not_scored``: its "held-out" VAF would be its in-sample one.

The data: the part's ``data`` (a path to a ``.mat`` or ``.npz`` holding the trials; the tests give the
developers' shared copy), else the file ``jointbench data fetch reklab`` stored
(:func:`jointbench.fitting.fetch.located`). With neither, each case records one ``not_run`` row saying how to
fetch it, and nothing else.

References
----------
Kearney, R. E. et al. REKLAB NLID toolbox (reklab/reklab_public, GPL-2): ``stiffnessID/experimental_data.mat``
and its analysis (decimation by 10 to 100 Hz). Ljung, L., System Identification: Theory for the User, 2nd ed.
(1999), sec. 16.4 (cross-validation: a model judged on data it was not fitted to).
"""
from __future__ import annotations

import dataclasses
import math
import time
from pathlib import Path
from typing import Literal

import numpy as np
from jointbench.benchmarks.protocols import Context, register
from jointbench.core.errors import InputError, Refused
from jointbench.core.schema import param
from jointbench.core.types import Trial


class NotCrossValidated(Exception):
    """An estimate whose prediction of a held-out record is that of the record it was fitted on (so its
    held-out VAF would be its in-sample VAF): recorded as ``not_scored``, never as a cross-validated VAF."""


@dataclasses.dataclass(frozen=True)
class CrossValParams:
    """Which trial, where the data are, and how each half is prepared."""

    trial: str = param("z_pf", doc="the trial: an array (or REKLAB nldat object) of the data file")
    data: str = param("", doc="the data file (.mat or .npz); empty: the one `jointbench data fetch reklab` stored")
    dataset: str = param("reklab", doc="the fetched data set read when `data` is empty")
    decimate: int = param(10, ge=1, doc="decimation factor of each half (REKLAB's analysis: 10, 1 kHz to 100 Hz)")
    decimate_filter: Literal["fir", "chebyshev"] = param("chebyshev", doc="anti-alias filter of the decimation "
                                                                          "(chebyshev: MATLAB's decimate, REKLAB's)")
    torque_sign: int = param(-1, doc="REKLAB's torque is positive opposite to JointBench's convention: -1")


def data_file(p: CrossValParams) -> Path | None:
    """The data file of the case: ``data`` when given, else the fetched data set, else None."""
    if p.data:
        path = Path(p.data).expanduser()
        if not path.is_file():
            raise InputError(f"realdata: data file {path} not found")
        return path
    from jointbench.fitting.fetch import located

    return located(p.dataset)


def halves(trial: Trial) -> tuple[Trial, Trial]:
    """The two halves of a recorded trial, of equal length, each with its own time base from 0."""
    n = trial.n // 2
    cut = [slice(0, n), slice(trial.n - n, trial.n)]
    return tuple(Trial.from_arrays(trial.angle[s], trial.torque[s], trial.fs, name=f"{trial.name} half {i + 1}")
                 for i, s in enumerate(cut))


def _fold(estimator, fit_on: Trial, test_on: Trial, p: CrossValParams):
    """``(vaf of the fitted half, vaf of the held-out half, fit seconds)`` of one fold."""
    from jointbench.fitting import pipeline

    kw = dict(torque_sign=p.torque_sign, decimate=p.decimate, decimate_filter=p.decimate_filter)
    train, _ = pipeline.prepare(estimator, [fit_on], **kw)
    test, _ = pipeline.prepare(estimator, [test_on], **kw)
    t0 = time.perf_counter()
    est = pipeline.fit_checked(estimator, train)
    seconds = time.perf_counter() - t0
    fitted = pipeline.gate(estimator, est, train)
    try:
        held_out = pipeline.score(est, test)
    except InputError as exc:                 # an estimate that predicts only the records it was fitted on
        raise NotCrossValidated(str(exc)) from None
    if np.array_equal(held_out[0].y, fitted[0].y):
        raise NotCrossValidated(f"{estimator.name}: its prediction of another record is the record it was fitted on "
                                f"(its Estimate.prediction ignores the record given): no held-out VAF")
    return fitted[0].vaf(), held_out[0].vaf(), seconds


@register("realdata.crossval", CrossValParams)
def crossval(ctx: Context) -> None:
    """Every estimator of the part on one recorded trial, two folds (module docstring)."""
    from jointbench.fitting.read import read_records_of

    p = ctx.params
    path = data_file(p)
    if path is None:
        ctx.metric("not_run", math.nan, trial=p.trial,
                   reason=f"no data: run `jointbench data fetch {p.dataset}` (or give the part's data: a .mat/.npz)")
        return
    trial = read_records_of(path, array=p.trial)[0]
    first, second = halves(trial)
    ctx.metric("n_samples", trial.n, trial=p.trial)
    for name, estimator in ctx.estimators.items():
        if "trial" not in type(estimator).accepts:
            ctx.metric("skipped", math.nan, name, trial=p.trial,
                       reason=f"takes {' or '.join(sorted(type(estimator).accepts))} only, not one recorded trial")
            continue
        vafs = []
        for fold, (a, b) in enumerate(((first, second), (second, first)), start=1):
            try:
                v_fit, v_cv, seconds = _fold(estimator, a, b, p)
            except Refused as exc:
                ctx.refused(name, exc, trial=p.trial, fold=fold)
                break
            except NotCrossValidated as exc:
                ctx.metric("not_scored", math.nan, name, trial=p.trial, fold=fold, reason=str(exc))
                break
            except InputError as exc:
                ctx.metric("not_fitted", math.nan, name, trial=p.trial, fold=fold, reason=str(exc))
                break
            ctx.metric("vaf_fit", v_fit, name, trial=p.trial, fold=fold)
            ctx.metric("vaf_cv", v_cv, name, trial=p.trial, fold=fold)
            ctx.metric("fit_time_s", seconds, name, trial=p.trial, fold=fold)
            vafs.append(v_cv)
        if len(vafs) == 2:
            ctx.metric("vaf_cv_mean", sum(vafs) / 2, name, trial=p.trial)
