"""Hints after a fit that succeeded but that the data say is probably not the fit the user wants: the first tries
of a lab user on recorded data (issue 37). Each hint is one line naming what was seen, with its number, and the
argument to change, worded as the caller gives arguments (``--torque-sign -1`` on the command line,
``torque_sign=-1`` in Python). A hint never changes a result; :func:`hints` is called by the pipeline
(:func:`jointbench.fitting.pipeline.fit`) and its lines are :attr:`~jointbench.fitting.pipeline.Fit.hints`.

* **The torque's sign** (:func:`sign_hint`): a stiffness whose whole 95 % interval is negative (with I and B,
  when fitted, negative too) is the signature of a torque recorded positive opposite to the angle, as in the
  REKLAB ankle recordings: a joint that resists being moved has a positive stiffness.
* **A reflex** (:func:`reflex_hint`): for a time-invariant estimator without a reflex pathway, the share of the
  torque's variance that the angle's velocity, delayed by 20 ... 400 ms and half-wave rectified in each
  direction, explains in what the model leaves (the input of the reflex pathway of a parallel cascade). A stretch
  reflex is torque the intrinsic model cannot hold; fitted anyway, it is folded into I, B and K (on a strong
  reflex ``ibk_irf`` reads B near 0 and I two or three times the foot's). The hint names ``parallel_cascade``.
"""
from __future__ import annotations

import numpy as np

from jointbench.core.errors import argument

#: the delays (s) of the reflex check's regressors: the shortest stretch-reflex latency at the ankle (about 40 ms,
#: Kearney, Stein & Parameswaran 1997) with margin down to 20 ms, and the reflex torque's extent (its IRF lasts about
#: 300 ms after the delay: the same paper's Fig. 5; REKLAB's PC_stiffnessID fits 0 ... 0.99 s, parallel_cascade's
#: default reflex_window 0.5 s)
REFLEX_LAGS = (0.02, 0.4)
#: the rate (Hz) the reflex check runs at: the reflex torque lies below 10 ... 15 Hz
REFLEX_RATE = 100.0
#: share of the torque's variance (as a fraction) that the reflex regressors must explain, in what the model left,
#: for the hint: a reflex pathway worth this many VAF points is worth fitting. A choice of what is worth saying,
#: not tuned to a result: on the REKLAB ankle trials (ibk_irf, decimated by 10) the share is 0.42 and 0.18
#: (plantarflexion) and 0.07, 0.02, 0.06 (dorsiflexion), where parallel_cascade's total VAF exceeds the intrinsic
#: IRF's alone by 26, 19 and 9, 2, 8 points; on simulated ankles without a reflex it is 0.000
REFLEX_SHARE = 0.05


def hints(estimator, estimate, trials: list, predictions: list, torque_sign: int = 1) -> list[str]:
    """Every hint for ``estimate``, fitted by ``estimator`` to ``trials`` (as fitted) with ``predictions``.

    Returns
    -------
    list of str
        One line per hint (none when nothing is seen); never raises.
    """
    out = []
    for rule in (sign_hint, reflex_hint):
        try:
            text = rule(estimator, estimate, trials, predictions, torque_sign)
        except Exception:  # noqa: BLE001 - a hint must never turn a fit that succeeded into an error
            text = None
        if text:
            out.append(text)
    return out


def sign_hint(estimator, estimate, trials, predictions, torque_sign: int = 1) -> str | None:
    """The torque-sign hint when the estimate's stiffness (``K``, or the low-frequency stiffness of a
    nonparametric estimate) and its whole 95 % interval are negative."""
    params = estimate.parameters()
    key = "K" if "K" in params else "stiffness"
    value = np.asarray(params[key], float) if key in params else np.atleast_1d(estimate.stiffness(estimate.time))
    bounds = estimate.intervals.bounds.get(key) if estimate.intervals is not None else None
    top = np.max(np.asarray(bounds[1], float)) if bounds is not None else np.max(value)
    if not (np.mean(value) < 0 and top < 0):
        return None
    also = [k for k in ("I", "B") if k in params and np.mean(params[k]) < 0]
    seen = f"{key} = {np.mean(value):.4g} N m/rad is negative" + (f" ({', '.join(also)} too)" if also else "")
    return (f"{seen}: a joint that resists being moved has a positive stiffness, so the torque is likely "
            f"recorded positive in the direction opposite to the angle (as in the REKLAB ankle recordings); fit "
            f"with {argument('torque_sign', -torque_sign)}")


def reflex_hint(estimator, estimate, trials, predictions, torque_sign: int = 1) -> str | None:
    """The reflex hint: for a time-invariant estimator without a reflex pathway, when :func:`reflex_share` of
    some record reaches :data:`REFLEX_SHARE`."""
    from jointbench import estimators

    tags = estimators.REGISTRY.tags(estimator.name) if estimator.name in estimators.REGISTRY.names() else ()
    if "lti" not in tags or "reflex" in tags:
        return None
    shares = [reflex_share(t, p) for t, p in zip(trials, predictions)]
    best = int(np.argmax(shares))
    if not shares[best] >= REFLEX_SHARE:
        return None
    a, b = (1e3 * x for x in REFLEX_LAGS)
    params = estimate.parameters()
    damping = ""
    if "B" in params and estimate.intervals is not None and "B" in estimate.intervals.bounds:
        lo = np.min(np.asarray(estimate.intervals.bounds["B"][0], float))
        if lo <= 0 < np.mean(params.get("K", 1.0)):
            damping = (f"; B = {np.mean(params['B']):.3g} N m s/rad, not clearly positive as a joint's damping "
                       f"is: the reflex torque folded into I and B")
    return (f"the angle's velocity {a:g} ... {b:g} ms earlier, rectified, explains {100 * shares[best]:.1f} % of "
            f"the torque's variance that {estimator.name} leaves in '{trials[best].name}' (the signature of a "
            f"stretch reflex, which an intrinsic model cannot hold){damping}; fit the intrinsic and reflex "
            f"pathways with {argument('estimator', 'parallel_cascade')}")


def reflex_share(trial, prediction) -> float:
    """The fraction of the torque's variance that the reflex pathway's input explains in the residual of a
    prediction: the residual ``y - yhat`` regressed (least squares, adjusted R^2) on the angle's velocity half-wave
    rectified in each direction, at lags :data:`REFLEX_LAGS`, at about :data:`REFLEX_RATE` Hz; times the
    residual's share of the torque's variance.

    References
    ----------
    Kearney, R. E., Stein, R. B. & Parameswaran, L. (1997). Identification of intrinsic and reflex contributions
    to human ankle stiffness dynamics. IEEE Trans. Biomed. Eng. 44(6), 493-504: the reflex pathway's input, the
    delayed half-wave rectified velocity (Fig. 1), and the parallel cascade fitting it to the intrinsic
    pathway's residual (Sec. II-C).
    """
    from scipy import signal as sps

    from jointbench.estimators import _reflex as rx

    used = np.asarray(prediction.used, bool)
    y = np.asarray(prediction.y, float)
    r = np.where(used, y - np.asarray(prediction.yhat, float), 0.0)
    u = np.asarray(trial.angle, float) - float(np.mean(trial.angle))
    q = max(1, int(trial.fs // REFLEX_RATE))
    if q > 1:
        r = sps.decimate(r, q, ftype="fir", zero_phase=True)
        u = sps.decimate(u, q, ftype="fir", zero_phase=True)
        used = used[::q][:len(r)]
    fs = trial.fs / q
    d = max(1, int(round(REFLEX_LAGS[0] * fs)))
    L = int(round(REFLEX_LAGS[1] * fs)) - d + 1
    v = rx.velocity(u, fs)
    X = np.concatenate([rx.lag_matrix(np.maximum(v, 0.0), d, L), rx.lag_matrix(np.maximum(-v, 0.0), d, L)], axis=1)
    rows = used.copy()
    rows[:d + L] = False
    n, p = int(rows.sum()), X.shape[1]
    if n < 4 * p:
        return 0.0
    X, e = X[rows] - X[rows].mean(axis=0), r[rows] - r[rows].mean()
    G, b = X.T @ X, X.T @ e                 # normal equations: 2p x 2p (the SVD of X took 0.2 s at 6000 x 78)
    coef = np.linalg.lstsq(G, b, rcond=None)[0]
    tss = float(e @ e)
    rss = max(tss - float(coef @ b), 0.0)
    if tss <= 0:
        return 0.0
    r2 = 1.0 - (rss / (n - p - 1)) / (tss / (n - 1))
    torque = y[np.asarray(prediction.used, bool)]
    return float(r2 * np.var(e) / np.var(torque))
