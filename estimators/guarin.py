"""Guarin & Kearney (2017): time-varying IRF expanded on basis functions of time, one LS problem."""
from __future__ import annotations

import dataclasses
from typing import Literal

import numpy as np
from numpy.polynomial import legendre
from scipy.interpolate import BSpline

from jointbench.estimators import register
from jointbench.estimators._reflex import VelocitySettings
from jointbench.estimators._resample import JackknifeSettings, realization_jackknife
from jointbench.estimators._tvirf import EnsembleEstimator, TVLagSettings, basis_normal, centred
from jointbench.core.ensemble import Ensemble
from jointbench.core.errors import InputError
from jointbench.core.intervals import psd_solve
from jointbench.core.differentiators import central
from jointbench.core.estimate import Prediction
from jointbench.core.estimate_tv import TVIRFEstimate
from jointbench.core.schema import Tune, param
from jointbench.core.signal import Differentiate, velocity

BasisKind = Literal["gaussian", "bspline", "legendre"]


def time_basis(kind: str, count: int, n: int, width: float = 1.0) -> np.ndarray:
    """Basis functions of time on ``n`` samples, shape ``(n, count)``.

    * ``gaussian``: ``exp(-(x - c_m)^2 / (2 sigma^2))`` with ``x = i / (n - 1)``, centres ``c_m`` equally
      spaced from one spacing before the record to one spacing after it (so the record's ends are
      covered like its middle: a least-squares combination then reproduces a constant to 0.2 % with
      21 functions, against 4 % with the outer centres on the ends), ``sigma = width x`` the spacing;
    * ``bspline``: cubic B-splines on equally spaced knots over [0, 1] (``count >= 4``); they sum to 1;
    * ``legendre``: Legendre polynomials ``P_0 ... P_{count-1}`` of ``2x - 1``.

    References
    ----------
    Guarin, D. L. & Kearney, R. E. (2017), Front. Comput. Neurosci. 11:51, Sec. 2 (the TV-IRF expanded
    on a set of basis functions of time).
    """
    x = np.linspace(0.0, 1.0, n)
    if kind == "legendre":
        return legendre.legvander(2 * x - 1, count - 1)
    if kind == "gaussian":
        if count == 1:
            return np.ones((n, 1))
        step = 1.0 / (count - 3) if count > 3 else 1.0 / max(count - 1, 1)
        c = np.linspace(-step, 1.0 + step, count) if count > 3 else np.linspace(0.0, 1.0, count)
        sigma = width * (c[1] - c[0])
        return np.exp(-0.5 * ((x[:, None] - c[None, :]) / sigma) ** 2)
    k = 3
    inner = np.linspace(0.0, 1.0, count - k + 1)
    knots = np.concatenate([np.zeros(k), inner, np.ones(k)])
    return BSpline.design_matrix(x, knots, k).toarray()


@dataclasses.dataclass(eq=False)
class GuarinEstimate(TVIRFEstimate):
    """The intrinsic TV-IRF (:class:`~jointbench.core.estimate.TVIRFEstimate`) plus, when fitted, the reflex
    pathway: the input's velocity delayed by ``reflex_delay`` samples, through ``nonlinearity``, then a
    causal TV-IRF ``reflex_h`` (lags ``0 ... reflex_lags - 1`` by time).

    :meth:`stiffness` is the intrinsic low-frequency gain (the reflex pathway is nonlinear: it has no
    gain of its own); :meth:`predict` is the sum of both pathways.
    """

    reflex_h: np.ndarray | None = None
    reflex_delay: int = 0
    nonlinearity: str = "rectifier"
    differentiate: Differentiate = "before_decimation"     #: where the fit took the velocity (its setting)

    def reflex_input(self, u: np.ndarray, v: np.ndarray | None = None) -> np.ndarray:
        """The reflex pathway's input: ``NL(u'(t - delay))``, the velocity ``v`` (default: central differences
        of ``u``)."""
        V = None if v is None else np.asarray(v, float)[:, None]
        return reflex_signal(np.asarray(u, float)[:, None], self.fs, self.reflex_delay, self.nonlinearity, V)[:, 0]

    def predict(self, u: np.ndarray, v: np.ndarray | None = None) -> np.ndarray:
        """Both pathways' torque for the angle ``u`` (its velocity ``v``: default, central differences of ``u``)."""
        y = super().predict(u)
        if self.reflex_h is None:
            return y
        x = self.reflex_input(u, v)
        lr = self.reflex_h.shape[0]
        from numpy.lib.stride_tricks import sliding_window_view
        Xr = sliding_window_view(np.concatenate([np.zeros(lr - 1), x]), lr)[:, ::-1]   # x(i - k), k = 0 ... lr-1
        return y + np.einsum("ik,ki->i", Xr, self.reflex_h)

    def prediction(self, trial, index: int = 0) -> Prediction:
        """As :meth:`TVIRFEstimate.prediction`, a reflex pathway driven by the trial's velocity as the fit took it
        (``differentiate``: :func:`jointbench.core.signal.velocity`)."""
        if self.reflex_h is None:
            return super().prediction(trial, index)
        y = trial.output - np.mean(trial.output)
        yhat = self.predict(trial.input - np.mean(trial.input), velocity(trial, self.differentiate))
        return Prediction(y, yhat, self.valid.copy(), "torque (mean removed) against the intrinsic and reflex "
                          "pathways' prediction from the angle (mean removed), on the samples where the "
                          f"time-varying IRF is estimated ({int(self.valid.sum())} of {len(self.valid)})")


def reflex_signal(U: np.ndarray, fs: float, delay: int, nonlinearity: str, V: np.ndarray | None = None) -> np.ndarray:
    """``NL(v(i - delay))`` for every column of ``U`` (zero before the delay), ``v`` the velocity: the columns of
    ``V``, or central differences of ``U`` (:func:`jointbench.core.differentiators.central`)."""
    v = central(U, fs) if V is None else V
    x = np.maximum(v, 0.0) if nonlinearity == "rectifier" else v
    out = np.zeros_like(x)
    out[delay:] = x[:len(x) - delay]
    return out


@register("guarin", tags=("ltv", "nonparametric", "irf", "ensemble"))
class Guarin(EnsembleEstimator):
    """Time-varying two-sided IRF whose coefficients are expanded on basis functions of time.

    ``h(k, t) = sum_m c_{k,m} phi_m(t)`` (:func:`time_basis`), so that
    ``y_r(t) = sum_k sum_m c_{k,m} phi_m(t) u_r(t - k)`` is linear in the ``L M`` coefficients, one
    least-squares problem over every sample of every realization (Guarin & Kearney combine the
    ensemble with a deterministic description of the time variation: few realizations suffice). The
    normal equations are formed without the regression matrix: with ``S(t) = sum_r x_r(t) x_r(t)^T``
    (lagged input) the Gram matrix is ``sum_t (phi(t) phi(t)^T) (x) S(t)``, one matrix product, and it
    is solved by a pseudo-inverse on unit-scaled columns (``rcond``).

    The reflex pathway (``reflex: true``) adds a parallel branch: the input's velocity delayed by
    ``reflex_delay``, through a half-wave rectifier (``nonlinearity``), then a causal time-varying IRF
    of ``reflex_lags`` expanded on the same basis; both pathways are estimated in the same linear
    least-squares problem (a simplification of the paper's iterative parallel-cascade fit, which
    expands the static nonlinearity and the reflex dynamics separately).

    Parameters
    ----------
    settings : Settings
        ``basis`` ('gaussian', 'bspline', 'legendre'), ``n_basis`` (M), ``width`` (Gaussian width in
        centre spacings); ``lag_before``, ``lag_after`` (s, default 0.04); ``remove_mean``
        ('record', 'ensemble', 'none'); ``edges`` ('valid': only samples whose lags lie in the record;
        'zero': zero input outside); ``reflex``, ``reflex_delay``, ``reflex_lags``, ``nonlinearity``,
        ``differentiate`` (where the reflex pathway's velocity is taken: :class:`estimators._reflex.
        VelocitySettings`); ``rcond``.

    Notes
    -----
    Takes one trial or an :class:`~jointbench.core.ensemble.Ensemble` (several records are taken as an
    ensemble). Raises :class:`InputError` when the basis is larger than the data can support: more
    unknowns than equations, or basis functions closer than two samples. Returns a
    :class:`GuarinEstimate` (``h`` not scaled by ``1/fs``; Guarin's scripts return ``h fs``), valid
    on the samples whose lags lie in the record (every sample with ``edges = 'zero'``).

    References
    ----------
    Guarin, D. L. & Kearney, R. E. (2017). Estimation of time-varying, intrinsic and reflex dynamic joint
    stiffness during movement. Application to the ankle joint. Front. Comput. Neurosci. 11:51.
    van de Ruit et al. (2018), Sec. V-E (the comparison with Guarin's method).
    """

    accepts = frozenset({"trial", "pooled", "ensemble"})

    @dataclasses.dataclass(frozen=True)
    class Settings(TVLagSettings, JackknifeSettings, VelocitySettings):
        basis: BasisKind = param("gaussian", doc="basis functions of time: 'gaussian', 'bspline' or 'legendre'")
        n_basis: int = param(21, ge=1, doc="number of basis functions M", tune=Tune())
        width: float = param(1.0, gt=0, doc="Gaussian width, in centre spacings")
        remove_mean: Literal["record", "ensemble", "none"] = param("record", doc="'record': each realization's "
                                                                                "mean; 'ensemble': the mean over "
                                                                                "realizations at every sample")
        edges: Literal["valid", "zero"] = param("valid", doc="'valid': only samples whose lags lie in the record; "
                                                             "'zero': the input is zero outside the record")
        reflex: bool = param(False, doc="add the reflex pathway (delayed velocity, rectifier, TV linear dynamics)")
        reflex_delay: float = param(0.04, unit="s", ge=0, doc="reflex delay")
        reflex_lags: float = param(0.1, unit="s", gt=0, doc="memory of the reflex dynamics (causal lags)")
        nonlinearity: Literal["rectifier", "linear"] = param("rectifier", doc="static nonlinearity of the reflex "
                                                                             "pathway: half-wave rectifier")

        def __post_init__(self):
            if self.basis == "bspline" and self.n_basis < 4:
                raise ValueError(f"n_basis = {self.n_basis}: cubic B-splines need at least 4")

    def _fit_ensemble(self, ens: Ensemble) -> GuarinEstimate:
        s = self.settings
        fs, n, R = ens.fs, ens.n, ens.size
        m1, m2 = self._lags(ens)
        L = m1 + m2 + 1
        M = s.n_basis
        U, Y = centred(self.name, ens, s.remove_mean)
        d = int(round(s.reflex_delay * fs))
        lr = max(1, int(round(s.reflex_lags * fs))) if s.reflex else 0
        first = m2 if s.edges == "valid" else 0
        last = n - m1 if s.edges == "valid" else n                  # rows: samples first ... last - 1
        if s.reflex and s.edges == "valid":
            first = max(first, d + lr)
        n_rows = last - first
        if n_rows < 1:
            raise InputError(f"{self.name}: the records of '{ens.name}' ({n} samples) are not longer than the lags "
                             f"(settings 'lag_before', 'lag_after', 'reflex_delay', 'reflex_lags')")
        where = (f"{self.name}: basis = '{s.basis}', n_basis = {M} on {n} samples ({n / fs:g} s) of "
                 f"'{ens.name}'")
        if M > max(1, n_rows // 2):
            raise InputError(f"{where}: the basis is finer than two samples; the data cannot support it "
                             f"(lower n_basis to at most {max(1, n_rows // 2)})")
        n_unknown = M * (L + lr)
        if n_unknown > R * n_rows:
            raise InputError(f"{where}: {M} x {L + lr} lags = {n_unknown} unknowns but only {R} x {n_rows} = "
                             f"{R * n_rows} equations; the data cannot support that basis: lower n_basis or the lags")
        pad = np.zeros((m2, R)), np.zeros((m1, R))
        X = np.lib.stride_tricks.sliding_window_view(np.concatenate([pad[0], U, pad[1]]), L, axis=0)[..., ::-1]
        X = X[first:last]                                            # (rows, R, L): row i is sample first + i
        if s.reflex:
            xr = reflex_signal(ens.inputs, fs, d, s.nonlinearity,
                               np.stack([velocity(t, s.differentiate) for t in ens], axis=1))
            if s.remove_mean == "record":            # centred like the output (the rectifier has a mean)
                xr = xr - xr.mean(axis=0)
            elif s.remove_mean == "ensemble":
                xr = xr - xr.mean(axis=1, keepdims=True)
            Xr = np.lib.stride_tricks.sliding_window_view(np.concatenate([np.zeros((lr - 1, R)), xr]), lr,
                                                          axis=0)[..., ::-1][first:last]
            X = np.concatenate([X, Xr], axis=2)
        Ly = X.shape[2]
        Yv = Y[first:last]
        Phi = time_basis(s.basis, M, n, s.width)[first:last]          # (rows, M)
        G, b = basis_normal(X, Yv, Phi)
        c, rank = psd_solve(G, b, s.rcond)
        c = c.reshape(M, Ly)                                          # c[m, k]
        B = time_basis(s.basis, M, n, s.width)                        # (n, M)
        H = (B @ c).T                                                 # (Ly, n)
        valid = np.zeros(n, bool)
        valid[first:last] = True
        info = {"realizations": R, "basis": f"{M} {s.basis}", "unknowns": n_unknown,
                "equations": R * n_rows, "rank": f"{rank} of {G.shape[0]}",
                "reflex": "yes" if s.reflex else "no"}
        est = GuarinEstimate(lags=np.arange(-m1, m2 + 1), h=H[:L], fs=fs, time=ens.time, valid=valid,
                              estimator=self.name, info=info, reflex_h=H[L:] if s.reflex else None,
                              reflex_delay=d, nonlinearity=s.nonlinearity, differentiate=s.differentiate)
        return est.with_intervals(lambda: realization_jackknife(self.name, ens, self._fit_ensemble, est, s))
