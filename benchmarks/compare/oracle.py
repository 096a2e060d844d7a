"""The oracle bound of a comparison scenario: how well an estimator that knows the form of the true K(t) does.

The oracle is not an estimator of the registry: it sees the truth of the simulation. It knows the structure
of the joint's impedance, ``tau(t) = I(t) theta''(t) + B(t) theta'(t) + K(t) theta(t)`` (the limb's own
angle, velocity and acceleration at the simulation rate, as the backend computed them), the *shape* of every
coefficient that varies in time (``c(t) = c0 + c1 s_c(t)``, ``s_c`` the true profile standardised), the torque
sensor's filter, the acquisition and the voluntary torque; it does not know the levels ``c0, c1`` nor the
sensor noise. It estimates the levels by ordinary least squares from the measured torque (the impedance
torque as acquired plus the realization's torque noise: :func:`regressors`, :func:`fit_levels`) and scores its
K-hat(t) exactly as the methods are scored (the static gain of the frozen impedance through the apparatus,
the same samples, the same realizations; :func:`oracle_errors`).

For a linear model ``y = X beta + e`` with white Gaussian noise of variance sigma^2, least squares is
unbiased with covariance ``sigma^2 (X^T X)^-1``, the Cramér–Rao bound of that parametric model
(:func:`crb_covariance`): no unbiased estimator that is given the same regressors does better. With
coloured noise (the wrist scenarios' 15 Hz noise filter; an anti-alias filter near the Nyquist rate)
least squares is still unbiased but no longer efficient, so the oracle's error lies above that model's
bound; with a stiffness that enters the scored static gain non-linearly (a hand contact in series) the
scored error is the bound's through that map.
A method's *efficiency* is its total error divided by the oracle's (:func:`efficiency`): 1 matches the
oracle, 2 is twice its error. A biased method (a smoother that pulls toward a constant) can score below
the oracle on a given realization set: the bound holds for unbiased estimators.

References
----------
Kay, *Fundamentals of Statistical Signal Processing: Estimation Theory* (1993), Theorem 4.1 (the linear
model: the minimum-variance unbiased estimator ``(X^T X)^-1 X^T y`` attains the Cramér–Rao bound,
covariance ``sigma^2 (X^T X)^-1``, eq. 4.9). van de Ruit, Mugge, Cavallo, Lataire, Ludvig & Schouten,
"Quantitative comparison of time-varying system identification methods to describe human joint impedance"
(the total error, metric 4).
"""
from __future__ import annotations

import dataclasses

import numpy as np
import pandas as pd

from jointbench import sims
from jointbench.benchmarks import metrics
from jointbench.benchmarks.compare.identifiability import torque_channel, without_torque_noise
from jointbench.benchmarks.compare.tables import PRIMARY_BACKEND, SCENARIO_ROWS
from jointbench.benchmarks.scoring import frozen_stiffness, scored_samples
from jointbench.sims.experiment import limb_response

#: the rows of the oracle (estimator ``(scenario)``): metric -> heading
ORACLE_METRICS = {
    "oracle_total_error": "oracle total error (N·m/rad), a bound",
    "oracle_bias_rms": "oracle bias, RMS (N·m/rad)",
    "oracle_random_error": "oracle random error (N·m/rad)",
    "oracle_total_error_ensemble": "oracle total error fitted to ensembles (N·m/rad), a bound",
}
#: how the tables name a method given ensembles (:func:`tables.labelled`)
ENSEMBLE_SUFFIX = " (ensemble)"
#: the impedance's coefficients and the limb signal each multiplies
COEFFICIENTS = (("I", "acceleration"), ("B", "velocity"), ("K", "angle"))


@dataclasses.dataclass(frozen=True)
class Column:
    """One regressor: coefficient ``name`` (I, B or K), its constant level (``shape`` None) or its
    variation (``shape``: the standardised true profile at the acquired samples)."""

    name: str
    shape: np.ndarray | None = None


def not_applicable(exp) -> str:
    """Why the oracle's model does not hold for ``exp`` ('' when it does): it needs an impedance linear in
    its coefficients (no reflex pathway, no coefficient that depends on the angle)."""
    parts = sims.backend.nonlinear_parts(exp)
    return f"the oracle needs an impedance linear in its coefficients, not one with {parts}" if parts else ""


def _check_linear(exp) -> None:
    reason = not_applicable(exp)
    if reason:
        raise ValueError(reason)


def regressors(exp, resp) -> tuple[np.ndarray, list[Column]]:
    """The oracle's regressors at the acquired samples and what each is (module docstring).

    For each coefficient ``c`` of the impedance (I, B, K) the limb's signal ``x`` it multiplies
    (acceleration, velocity, angle of ``resp``, at the simulation rate) and, when ``c`` varies in time,
    ``x (c(t) - mean c) / sd c``; every column through the torque sensor's filter and the acquisition, the
    path of the measured torque, so that the acquired impedance torque is ``X beta`` exactly.

    Parameters
    ----------
    exp : sims.Experiment
        The experiment (its joint gives the true coefficients' shapes).
    resp : sims.backend.Response
        The limb's response (:func:`sims.experiment.limb_response`).
    """
    _check_linear(exp)
    t_sim = np.arange(exp.n_sim) / exp.fs_sim
    at_sim = exp.joint.coefficients_at(t_sim)
    at_acq = exp.joint.coefficients_at(exp.acquired_times())
    cols, layout = [], []
    for (name, signal), c, c_acq in zip(COEFFICIENTS, at_sim, at_acq):
        x = np.asarray(getattr(resp, signal), float)
        cols.append(x)
        layout.append(Column(name))
        c = np.asarray(c, float)
        if np.ptp(c) > 0:
            mean, sd = float(c.mean()), float(c.std())
            cols.append(x * (c - mean) / sd)
            layout.append(Column(name, (np.asarray(c_acq, float) - mean) / sd))
    X = exp.acquire(exp.sensors.torque.filtered(np.column_stack(cols), exp.fs_sim))
    return np.asarray(X, float), layout


def fit_levels(X: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Ordinary least squares ``argmin |y - X beta|`` (columns scaled to unit norm for the solve).

    References
    ----------
    Kay (1993), eq. 4.9 (the linear model's efficient estimator).
    """
    scale = np.linalg.norm(X, axis=0)
    scale[scale == 0] = 1.0
    beta, *_ = np.linalg.lstsq(X / scale, y, rcond=None)
    return beta / scale


def crb_covariance(X: np.ndarray, sigma2: float) -> np.ndarray:
    """The Cramér–Rao bound of the linear model ``y = X beta + e``, ``e`` white Gaussian of variance
    ``sigma2``: ``sigma2 (X^T X)^-1``, the covariance of :func:`fit_levels` in that model.

    References
    ----------
    Kay (1993), Theorem 4.1, eq. 4.9.
    """
    return float(sigma2) * np.linalg.inv(X.T @ X)


def coefficients(beta: np.ndarray, layout: list[Column], n: int) -> dict[str, np.ndarray]:
    """The estimated coefficients at the ``n`` acquired samples: ``c0 + c1 s_c(t)`` per coefficient."""
    out = {name: np.zeros(n) for name, _ in COEFFICIENTS}
    for b, col in zip(beta, layout):
        out[col.name] = out[col.name] + (b if col.shape is None else b * col.shape)
    return out


def scored_stiffness(exp, trial, coefs: dict[str, np.ndarray]) -> np.ndarray:
    """The stiffness the methods are scored against, from the estimated coefficients instead of the true
    ones: the static gain of the frozen impedance through the apparatus
    (:meth:`~jointbench.core.types.Trial.frozen_stiffness` of the trial with these coefficients)."""
    Z = np.column_stack([coefs["I"], coefs["B"], coefs["K"]])
    num, den = exp.apparatus.coupling(exp.joint).frozen_response(Z, exp.apparatus.imposed,
                                                                 exp.apparatus.angle_is_drive)
    truth = dataclasses.replace(trial.truth, I=coefs["I"], B=coefs["B"], K=coefs["K"], num=num, den=den)
    return frozen_stiffness(trial.replace(truth=truth))


def realization_data(exp, seed, realization: int) -> tuple[np.ndarray, np.ndarray, list[Column], object]:
    """``(X, y, layout, trial)`` of one realization: the oracle's regressors (:func:`regressors`), the torque
    it fits (the acquired impedance torque of the truth plus the realization's torque noise: the measured
    torque minus the same realization simulated without it) and the trial."""
    trial = sims.simulate(exp, seed, realization=realization, name=f"realization {realization}")
    clean = sims.simulate(without_torque_noise(exp), seed, realization=realization,
                          name=f"realization {realization} (no noise)")
    y = np.asarray(trial.truth.signals["torque"], float) + (torque_channel(trial) - torque_channel(clean))
    resp, _ = limb_response(exp, seed, realization)
    X, layout = regressors(exp, resp)
    return X, y, layout, trial


def oracle_estimate(exp, data: list[tuple]) -> np.ndarray:
    """The oracle's estimate of the scored stiffness at every sample, fitted to one realization or to an
    ensemble of them (``data``: :func:`realization_data` of each; the levels fitted to the stacked
    regressors, the time variation being the same in every realization)."""
    X = np.vstack([d[0] for d in data])
    y = np.concatenate([d[1] for d in data])
    layout, trial = data[0][2], data[0][3]
    beta = fit_levels(X, y)
    return scored_stiffness(exp, trial, coefficients(beta, layout, len(data[0][1])))


def oracle_errors(exp, seed, realizations: int, discard: float, ensemble_size: int = 0) -> dict[str, float]:
    """The oracle's total error, bias (RMS) and random error over realizations ``0 .. realizations - 1``
    (the methods' realizations), on the samples at least ``discard`` s from both ends: the metrics of
    :mod:`benchmarks.metrics`, as for every method. With ``ensemble_size`` M >= 2 also
    ``oracle_total_error_ensemble``: the oracle fitted to the ensembles the ensemble methods get
    (realizations r, r + R, ..., r + (M - 1) R for realization r)."""
    R = realizations
    data = {r: realization_data(exp, seed, r) for r in range(R)}
    trial = data[0][3]
    keep = scored_samples(trial.time, discard)
    kc = frozen_stiffness(trial)[keep]
    K = np.asarray([oracle_estimate(exp, [data[r]])[keep] for r in range(R)])
    b_rms, _ = metrics.bias(kc, K)
    out = {"oracle_total_error": metrics.total_error(kc, K), "oracle_bias_rms": b_rms,
           "oracle_random_error": metrics.random_error(K)}
    if ensemble_size >= 2:
        E = []
        for r in range(R):
            members = [data[r]] + [realization_data(exp, seed, r + R * m) for m in range(1, ensemble_size)]
            E.append(oracle_estimate(exp, members)[keep])
        out["oracle_total_error_ensemble"] = metrics.total_error(kc, np.asarray(E))
    return out


def fits_ensembles(backend: str) -> bool:
    """Whether the oracle is also fitted to ensembles on ``backend``: on the ranked one (no backend axis:
    the default), where the ensemble methods run and efficiency is reported."""
    return backend in ("", PRIMARY_BACKEND)


def trials_estimate(realizations: int, ensemble_size: int, backend: str) -> int:
    """Trials' worth of acquisitions :func:`oracle_errors` makes in an identifiability case (for the grid's
    budget estimate): each realization acquired with and without noise and its regressors filtered and
    acquired like a third, R of them, times M on the ranked backend (its ensembles, as the protocol asks)."""
    return 3 * realizations * (ensemble_size if fits_ensembles(backend) else 1)


# ----------------------------------------------------------------------------------- the report's side
def oracle_table(rows: pd.DataFrame) -> pd.DataFrame:
    """One row per cell and backend with the oracle's figures (labelled rows, :func:`tables.labelled`)."""
    sel = rows[(rows["estimator"] == SCENARIO_ROWS) & rows["metric"].isin(list(ORACLE_METRICS))]
    if sel.empty:
        return pd.DataFrame(columns=["cell", "backend", *ORACLE_METRICS])
    out = sel.pivot_table(index=["cell", "backend"], columns="metric", values="value", aggfunc="median")
    return out.reset_index().rename_axis(columns=None)


def efficiency(table: pd.DataFrame, rows: pd.DataFrame) -> pd.DataFrame:
    """Every method's total error divided by the oracle's on the same cell and backend (an ensemble method's
    by the oracle fitted to the same ensembles): one row per cell, backend, method and tuning with
    ``total_error``, ``oracle_total_error`` (the bound it is divided by) and ``efficiency`` (NaN where
    either is missing or not finite). ``table``: the full table (:func:`tables.full_table`); ``rows``: the
    labelled tidy rows."""
    cols = ["cell", "backend", "method", "tuning", "total_error", "oracle_total_error", "efficiency"]
    orc = oracle_table(rows)
    tot = table[table["metric"] == "total_error"][["cell", "backend", "method", "tuning", "value"]]
    if tot.empty or orc.empty:
        return pd.DataFrame(columns=cols)
    bound = orc.reindex(columns=["cell", "backend", "oracle_total_error", "oracle_total_error_ensemble"])
    out = tot.rename(columns={"value": "total_error"}).merge(bound, on=["cell", "backend"], how="left")
    ens = out["method"].str.endswith(ENSEMBLE_SUFFIX)
    out["oracle_total_error"] = out["oracle_total_error"].where(~ens, out["oracle_total_error_ensemble"])
    ok = np.isfinite(out["total_error"]) & (out["oracle_total_error"] > 0)
    out["efficiency"] = np.where(ok, out["total_error"] / out["oracle_total_error"].where(ok, 1.0), np.nan)
    return out[cols].reset_index(drop=True)


def bound_text(eff: pd.DataFrame, primary: str) -> str:
    """The report's paragraph on the oracle: what it assumes (module docstring) and, from ``eff``, the
    range of efficiencies on the primary backend and how many method-scenario pairs fall below 1."""
    text = ("Oracle bound: per scenario, the error of an estimator that knows the form of the true K(t). It knows "
            "the structure of the impedance (I theta'' + B(t) theta' + K(t) theta of the limb's own angle, "
            "velocity and acceleration), the shape of every coefficient that varies in time (K(t) = K0 + K1 s(t) "
            "with s the true profile), the sensors' filters, the acquisition and the voluntary torque; not the "
            "levels K0, K1 (nor I, B) and not the sensor noise, which it meets in the same realizations as every "
            "method. It fits the levels by least squares on the measured torque and is scored like the methods "
            "(static gain of the frozen impedance, same samples, same realizations). For a linear model with "
            "white Gaussian noise least squares attains the Cramér–Rao bound of that parametric model "
            "(sigma^2 (X^T X)^-1; Kay 1993, Theorem 4.1): no unbiased estimator given the same regressors does "
            "better. With coloured noise (the wrist's 15 Hz noise filter, a decimation's anti-alias filter near "
            "the Nyquist rate) it is unbiased but not efficient: the bound is then that of least squares, above "
            "the Cramér–Rao bound. The oracle sees the truth: it is a bound, not an estimator of the "
            "registry, and it is never ranked. Efficiency = a method's total error / the oracle's (1: as good as "
            "the oracle).")
    sel = eff[(eff["backend"] == primary) & np.isfinite(eff["efficiency"])] if not eff.empty else eff
    if sel.empty:
        return text + " No efficiency could be computed in this run (no oracle rows or no total error)."
    e = sel["efficiency"].to_numpy(float)
    text += (f" On the {primary} backend the efficiencies of {len(sel)} method-scenario-column values span "
             f"{e.min():.3g} to {e.max():.3g} (median {np.median(e):.3g}).")
    below = sel[sel["efficiency"] < 1]
    if len(below):
        text += (f" {len(below)} lie below 1 (biased estimates whose error over these realizations is smaller "
                 "than the unbiased oracle's; the bound holds for unbiased estimators): "
                 + "; ".join(f"{r.method}, {r.tuning}, on {r.cell} {r.efficiency:.2f}"
                             for r in below.sort_values("efficiency").head(5).itertuples())
                 + ("; ..." if len(below) > 5 else "") + ".")
    return text

