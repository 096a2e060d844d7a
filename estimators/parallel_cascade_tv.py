"""Time-varying parallel cascade on an ensemble: Guarin & Kearney's intrinsic and reflex pathways, with the
reflex nonlinearity estimated and the iterative parallel-cascade fit."""
from __future__ import annotations

import dataclasses
from typing import Literal

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view

from jointbench.estimators import register
from jointbench.estimators import _reflex as rx
from jointbench.estimators._tvirf import (EnsembleEstimator, TVLagSettings, basis_normal, basis_rhs, centred,
                                          lag_samples, blas_single_thread)
from jointbench.estimators.guarin import BasisKind, time_basis
from jointbench.core.ensemble import Ensemble
from jointbench.core.errors import InputError
from jointbench.core.intervals import psd_solve
from jointbench.core.scores import vaf
from jointbench.core.estimate import Prediction
from jointbench.core.estimate_tv import TVIRFEstimate
from jointbench.core.schema import Tune, param
from jointbench.core.signal import Differentiate, velocity

#: most alternations of gain and cascade in one parallel-cascade iteration (:meth:`TVParallelCascade._reflex`), and
#: in the first one, which starts from a constant gain (later ones start from the last iteration's gain, so an
#: alternation cut short continues there): bounds on the work, not the stopping rule (on the test suite's ensembles
#: :data:`GAIN_RTOL` stops them after 4 ... 10 and 8 ... 20; the caps are reached at times)
GAIN_ITERATIONS, FIRST_GAIN_ITERATIONS = 10, 20
#: the alternation stops when the residual falls by at most this fraction of itself: it then moves a VAF by at most
#: 1e-7 percentage points, far below the iteration's ``tolerance`` (0.01 by default)
GAIN_RTOL = 1e-9


#: what a fit of one trial says beside its numbers (``fit_info["advice"]``, printed by ``jointbench estimate``). Guarin
#: & Kearney (2017) separate the response to the perturbation from a change of operating point (the movement, a
#: voluntary torque) by an ensemble of realizations of the same time course, whose mean holds the latter
#: (``remove_mean='ensemble'``); one trial has none, and the basis functions of time then fit the movement's torque
#: as time-varying stiffness and reflex gain: on the issue-37 ankle trial with a movement, K(t) of one trial
#: correlated 0.69 with REKLAB's parameter-varying cascade (issue 37). On simulated trials without a movement one
#: trial is not worse in the delay: 6 samples (truth 4) on each of five 22 s realizations and on their ensemble.
SINGLE_TRIAL = ("one trial: the time-varying IRF and reflex gain are fitted to this record alone; an ensemble of "
                "realizations of the same time course (remove_mean='ensemble') is what separates the response to the "
                "perturbation from a movement or voluntary torque, which one trial fits as varying stiffness and "
                "reflex gain: give several realizations, or fit stiffness as a function of position from one trial "
                "with pv_irf and a schedule")


@dataclasses.dataclass(eq=False)
class TVCascadeEstimate(TVIRFEstimate):
    """The intrinsic TV-IRF (:class:`~jointbench.core.estimate_tv.TVIRFEstimate`: ``h`` lags x time, its
    :meth:`stiffness`) and the reflex pathway ``g(t) sum_k h_R(k) N(v(t - d - k))``: a time-varying gain
    ``reflex_gain`` on a Hammerstein cascade (``nonlinearity``, ``reflex_h`` on lags ``reflex_delay ...``);
    ``reflex_h`` is None when the pathway was not kept. VAFs as :class:`estimators.parallel_cascade.
    ParallelCascadeEstimate` (over every realization's valid samples)."""

    reflex_h: np.ndarray | None = None
    reflex_gain: np.ndarray | None = None
    reflex_delay: int = 0
    nonlinearity: rx.StaticNonlinearity | None = None
    vaf_total: float = float("nan")
    vaf_intrinsic: float = float("nan")
    vaf_reflex: float = 0.0
    differentiate: Differentiate = "before_decimation"     #: where the fit took the velocity (its setting)

    def reflex_torque(self, u: np.ndarray, v: np.ndarray | None = None) -> np.ndarray:
        """The reflex pathway's torque for an angle ``u`` on the fitted time base, with its velocity ``v``
        (default: central differences of ``u``); zeros without one."""
        u = np.asarray(u, float)
        if self.reflex_h is None:
            return np.zeros(len(u))
        v = rx.velocity(u, self.fs) if v is None else np.asarray(v, float)
        x = self.nonlinearity(v) - self.nonlinearity.offset
        return self.reflex_gain * (rx.lag_matrix(x, self.reflex_delay, len(self.reflex_h)) @ self.reflex_h)

    def intrinsic_torque(self, u: np.ndarray) -> np.ndarray:
        return TVIRFEstimate.predict(self, u)

    def predict(self, u: np.ndarray, v: np.ndarray | None = None) -> np.ndarray:
        """Both pathways' torque for the angle ``u`` (its velocity ``v``: default, central differences of ``u``)."""
        return self.intrinsic_torque(u) + self.reflex_torque(u, v)

    def prediction(self, trial, index: int = 0) -> Prediction:
        """As :meth:`TVIRFEstimate.prediction`, the reflex pathway driven by the trial's velocity as the fit took
        it (``differentiate``: :func:`jointbench.core.signal.velocity`)."""
        y = trial.output - np.mean(trial.output)
        yhat = self.predict(trial.input - np.mean(trial.input), velocity(trial, self.differentiate))
        return Prediction(y, yhat, self.valid.copy(), "torque (mean removed) against the intrinsic and reflex "
                          "pathways' prediction from the angle (mean removed), on the samples where the "
                          f"time-varying IRF is estimated ({int(self.valid.sum())} of {len(self.valid)})")

    def summary(self):
        out = super().summary()
        out.update({"vaf_total": self.vaf_total, "vaf_intrinsic": self.vaf_intrinsic, "vaf_reflex": self.vaf_reflex})
        return out


@dataclasses.dataclass(frozen=True, eq=False)
class Rows:
    """The ensemble on the fitted rows ``first ... last - 1`` (every lag of both pathways inside the record),
    shared by the delay scan and the cascade.

    Attributes
    ----------
    XI : ndarray (N, R, LI)
        The intrinsic pathway's lagged angle, lags ``-m1 ... m2``.
    Ph : ndarray (N, M)
        The basis functions of time.
    GI, bI : ndarray
        The intrinsic pathway's normal equations on the basis (the pathway alone).
    V : ndarray (n, R)
        The velocity on every sample.
    Yv : ndarray (N, R)
        The torque.
    first, last, W : int
        The fitted rows and the last lag of the reflex window.
    scale : float
        The largest speed ``v_max`` (the polynomial nonlinearity's range).
    """

    XI: np.ndarray
    Ph: np.ndarray
    GI: np.ndarray
    bI: np.ndarray
    V: np.ndarray
    Yv: np.ndarray
    first: int
    last: int
    W: int
    scale: float

    @classmethod
    def of(cls, U: np.ndarray, Y: np.ndarray, V: np.ndarray, Phi: np.ndarray, m1: int, m2: int, W: int) -> "Rows":
        """From the centred angle ``U``, torque ``Y``, velocity ``V`` (n x R), the time basis ``Phi`` (n x M), the
        intrinsic lags ``-m1 ... m2`` and the reflex window's last lag ``W``."""
        (n, R), first = U.shape, max(m2, W)
        last = n - m1
        XI = sliding_window_view(np.concatenate([np.zeros((m2, R)), U, np.zeros((m1, R))]), m1 + m2 + 1,
                                 axis=0)[..., ::-1][first:last]
        Ph, Yv = Phi[first:last], Y[first:last]
        GI, bI = basis_normal(XI, Yv, Ph)
        return cls(XI=XI, Ph=Ph, GI=GI, bI=bI, V=V, Yv=Yv, first=first, last=last, W=W,
                   scale=float(np.max(np.abs(V))))


@dataclasses.dataclass(frozen=True, eq=False)
class Cascade:
    """The parallel-cascade fit at one delay (:meth:`TVParallelCascade._cascade`).

    Attributes
    ----------
    a, h : ndarray
        The nonlinearity's coefficients and the reflex IRF (before :func:`estimators._reflex.finish`).
    gain : ndarray (N,)
        The reflex gain on the fitted rows.
    intrinsic, reflex : ndarray (N, R)
        Each pathway's output on the fitted rows.
    coef : ndarray (M, LI)
        The intrinsic TV-IRF's coefficients on the time basis.
    rss_intrinsic : float
        The residual of the intrinsic pathway alone (the first iteration's), on the same rows.
    iterations : int
        Parallel-cascade iterations.
    """

    a: np.ndarray
    h: np.ndarray
    gain: np.ndarray
    intrinsic: np.ndarray
    reflex: np.ndarray
    coef: np.ndarray
    rss_intrinsic: float
    iterations: int


@register("tv_parallel_cascade", tags=("ltv", "nonparametric", "irf", "ensemble", "reflex"))
class TVParallelCascade(EnsembleEstimator):
    """Time-varying intrinsic and reflex stiffness from an ensemble, by an iterative parallel cascade.

    Intrinsic pathway: the two-sided TV-IRF of Guarin & Kearney (2017), ``h_I(k, t) = sum_m c[m, k]
    phi_m(t)`` on basis functions of time (:func:`estimators.guarin.time_basis`). Reflex pathway: the
    delayed velocity through a static nonlinearity and a causal IRF (a Hammerstein cascade,
    :mod:`estimators._reflex`: rectifier, linear or an estimated polynomial), scaled by a gain that varies
    in time on the same basis, ``g(t) = sum_m e_m phi_m(t)``. The parallel-cascade procedure of Kearney et
    al. (1997) alternates between the pathways, each fitted to the torque minus the other's output, and
    within the reflex pathway between its gain and its cascade (each linear given the other), until the
    total VAF improves by less than ``tolerance``. The delay (unless fixed) is chosen first, by the joint
    fit of both pathways over every realization (:meth:`_delay`), then once more with the gain the first
    cascade found (and the cascade refitted if the delay changes). :class:`estimators.guarin.Guarin`'s
    ``reflex: true`` fits a fixed rectifier and a
    TV reflex IRF in one linear problem instead: the shortcut this estimator completes.

    Parameters
    ----------
    settings : Settings
        ``basis``, ``n_basis``, ``width`` (as Guarin); ``lag_before``, ``lag_after`` (s, default 0.04);
        ``remove_mean`` ('record', 'ensemble'); the reflex pathway and iteration as
        :class:`estimators.parallel_cascade.ParallelCascade` (``reflex_window`` default 0.3 s here).

    Notes
    -----
    Takes an ensemble (or one trial: an ensemble of one, fitted with :data:`SINGLE_TRIAL` as its advice). Returns a
    :class:`TVCascadeEstimate`, valid on the samples both pathways' lags reach in every realization.

    References
    ----------
    Guarin, D. L. & Kearney, R. E. (2017). Estimation of time-varying, intrinsic and reflex dynamic joint
    stiffness during movement. Application to the ankle joint. Front. Comput. Neurosci. 11:51.
    Kearney, R. E., Stein, R. B. & Parameswaran, L. (1997). IEEE Trans. Biomed. Eng. 44(6), 493-504.
    """

    accepts = frozenset({"trial", "pooled", "ensemble"})

    @dataclasses.dataclass(frozen=True)
    class Settings(rx.ReflexSettings, TVLagSettings):
        basis: BasisKind = param("gaussian", doc="basis functions of time: 'gaussian', 'bspline' or 'legendre'")
        n_basis: int = param(11, ge=1, doc="number of basis functions M", tune=Tune())
        width: float = param(1.0, gt=0, doc="Gaussian width, in centre spacings")
        remove_mean: Literal["record", "ensemble"] = param("record", doc="mean removed from each realization, or "
                                                                         "the ensemble mean at every sample")
        reflex_window: float = param(0.3, unit="s", gt=0, doc="lag window of the reflex IRF, from lag 0")

    def _fit_ensemble(self, ens: Ensemble) -> TVCascadeEstimate:
        s = self.settings
        fs, n, R = ens.fs, ens.n, ens.size
        m1, m2 = lag_samples(s, fs)
        LI, M = m1 + m2 + 1, s.n_basis
        U, Y = centred(self.name, ens, s.remove_mean)
        V = np.stack([velocity(t, s.differentiate) for t in ens], axis=1)      # (n, R): U's velocity
        if s.remove_mean == "ensemble":
            V = V - V.mean(axis=1, keepdims=True)
        rx.check_moving(self.name, V)
        cands, W = rx.delays(self.name, s, fs)
        first, last = max(m2, W), n - m1
        N = last - first
        p = 1 if s.nonlinearity != "polynomial" else s.order
        n_unknown = M * LI + M + p * (W - int(cands[0]) + 1)
        if N < 2 or R * N < 2 * n_unknown:
            raise InputError(f"{self.name}: '{ens.name}' ({R} x {n} samples) leaves {R} x {max(N, 0)} samples past the "
                             f"lags for {n_unknown} unknowns ({M} x {LI} intrinsic, {M} gains, {p} x "
                             f"{W - int(cands[0]) + 1} reflex); use "
                             f"longer records, fewer basis functions, shorter lags or a shorter reflex_window")
        data = Rows.of(U, Y, V, time_basis(s.basis, M, n, s.width), m1, m2, W)
        d, fit = self._delay_and_cascade(data, cands)
        rss = float(np.sum((data.Yv - fit.intrinsic - fit.reflex) ** 2))
        k_I, k_R = M * LI, M + (W - d + 1) + (p - 1 if p > 1 else 0)
        keep = s.keep_reflex == "always" or rx.mdl(rss, k_I + k_R, R * N) < rx.mdl(fit.rss_intrinsic, k_I, R * N)
        if keep:
            tqI, tqR, cI = fit.intrinsic, fit.reflex, fit.coef
            nl, h = rx.finish(fit.a, fit.h, s, data.scale)
        else:                                                       # the intrinsic pathway alone, refitted
            cI = psd_solve(data.GI, data.bI, s.rcond)[0].reshape(M, LI)
            tqI, tqR = np.einsum("trl,tm,ml->tr", data.XI, data.Ph, cI), np.zeros_like(data.Yv)
            nl, h = None, None
        info = {"realizations": R, "basis": f"{M} {s.basis}", "reflex_delay": f"{d / fs * 1e3:g} ms",
                "iterations": fit.iterations,
                "reflex": ("kept (MDL)" if s.keep_reflex == "mdl" else "kept (always)") if keep
                else "not kept: it does not lower the MDL against the intrinsic pathway alone"}
        if keep:
            info["nonlinearity"] = nl.describe()
        if R == 1:
            info["advice"] = SINGLE_TRIAL
        def vt(yhat):                                               # about each realization's mean
            return vaf(data.Yv, yhat, bias_counts=True, axis=0, undefined="nan")

        valid = np.zeros(n, bool)
        valid[first:last] = True
        H = np.ascontiguousarray(_on_record(data.Ph @ cI, first, last, n).T)     # (LI, n)
        return TVCascadeEstimate(lags=np.arange(-m1, m2 + 1), h=H, fs=fs, time=ens.time, valid=valid,
                                 estimator=self.name, info=info, reflex_h=h if keep else None,
                                 reflex_gain=_on_record(fit.gain, first, last, n) if keep else None, reflex_delay=d,
                                 nonlinearity=nl, vaf_total=vt(tqI + tqR), vaf_intrinsic=vt(tqI),
                                 vaf_reflex=vt(tqR) if keep else 0.0, differentiate=s.differentiate)

    def _delay_and_cascade(self, data: Rows, cands: np.ndarray) -> tuple[int, Cascade]:
        """The delay and the cascade fitted at it: a fixed delay's, or the delay of the joint fit with a constant
        gain (:meth:`_delay`), then once more with the gain the cascade found there (and the cascade refitted if
        the delay changes)."""
        if len(cands) == 1:
            d = int(cands[0])
            return d, self._cascade(d, data)
        d = self._delay(data, cands, np.ones(data.last - data.first))
        fit = self._cascade(d, data)
        d2 = self._delay(data, cands, fit.gain)
        if d2 != d:
            d, fit = d2, self._cascade(d2, data)
        return d, fit

    def _cascade(self, d: int, data: Rows) -> Cascade:
        """The parallel-cascade iteration at delay ``d``: the intrinsic TV-IRF fitted to the torque minus the
        reflex pathway's output (zero at first), the reflex pathway (:meth:`_reflex`) to the torque minus the
        intrinsic output, until the total VAF improves by less than ``tolerance`` (or ``max_iter``)."""
        s = self.settings
        XI, Ph, Yv = data.XI, data.Ph, data.Yv
        N, R, LI = XI.shape
        M = Ph.shape[1]
        L = data.W - d + 1
        B = rx.basis(data.V, s, data.scale)                         # (n, R, p): not centred (see _reflex)
        XR = np.stack([rx.lag_matrix(B[:, r], d, L) for r in range(R)], axis=1)[data.first:data.last]  # (N, R, p, L)
        g = np.ones(N)
        tqR = np.zeros_like(Yv)
        best, it, rss_I = -np.inf, 0, None
        for it in range(1, s.max_iter + 1):
            bI = basis_rhs(XI, Yv - tqR, Ph)
            cI = psd_solve(data.GI, bI, s.rcond)[0].reshape(M, LI)
            tqI = np.einsum("trl,tm,ml->tr", XI, Ph, cI)
            if rss_I is None:
                rss_I = float(np.sum((Yv - tqI) ** 2))
            a, h, g, tqR = self._reflex(XR, Yv - tqI, Ph, g, it == 1)
            total = vaf(Yv, tqI + tqR, bias_counts=True, axis=0)
            if total - best < s.tolerance:
                break
            best = total
        return Cascade(a=a, h=h, gain=g, intrinsic=tqI, reflex=tqR, coef=cI, rss_intrinsic=rss_I, iterations=it)

    def _reflex(self, XR: np.ndarray, Y: np.ndarray, Ph: np.ndarray, g: np.ndarray, start: bool):
        """The reflex pathway ``g(t) sum_k h(k) N_a(v(t - d - k))`` fitted to ``Y`` (rows x R) from the gain ``g``:
        alternately the cascade given the gain (normal equations of the products,
        :func:`estimators._reflex.hammerstein`) and the gain on the time basis given the cascade (at most
        :data:`GAIN_ITERATIONS` alternations, :data:`FIRST_GAIN_ITERATIONS` when ``start``, until
        :data:`GAIN_RTOL`); returns ``a, h, g, output``.

        The nonlinearity's output is not centred before the gain: a rectified velocity has a mean, and a
        varying gain turns it into a slow torque (the reflex tone follows the gain), which is part of the
        pathway. Each realization's regressors are centred instead (the torque's mean is removed)."""
        s = self.settings
        N, R, p, L = XR.shape

        def centred(X):
            return X - X.mean(axis=0, keepdims=True)

        prev = np.inf
        for _ in range(FIRST_GAIN_ITERATIONS if start else GAIN_ITERATIONS):
            Xg = centred(XR * g[:, None, None, None]).reshape(N * R, p * L)
            G, b = Xg.T @ Xg, Xg.T @ Y.reshape(N * R)
            a, h = rx.hammerstein(G, b, p, L)
            z = np.einsum("trpl,p,l->tr", XR, a, h)                  # the cascade's output, gain 1
            Zf = centred(z[:, :, None] * Ph[:, None, :]).reshape(N * R, -1)
            e = psd_solve(Zf.T @ Zf, Zf.T @ Y.reshape(N * R), s.rcond)[0]
            g = Ph @ e
            mean_g = float(np.mean(g))
            if mean_g != 0:                                          # the cascade carries the mean gain
                g, h = g / mean_g, h * mean_g
            out = centred(g[:, None] * np.einsum("trpl,p,l->tr", XR, a, h))
            rss = float(np.sum((Y - out) ** 2))
            if prev - rss <= GAIN_RTOL * max(rss, 1e-300):
                break
            prev = rss
        return a, h, g, out

    def _delay(self, data: Rows, cands: np.ndarray, gain: np.ndarray) -> int:
        """The delay of the joint fit of both pathways over every realization, the intrinsic IRF on the time
        basis (a time-invariant one would leave the variation of K in the residual and hide the reflex's
        first lags), the reflex IRF time-invariant on the lags ``d ... W`` scaled by ``gain(t)`` (1, or the
        gain of a first fit: a modulated reflex's small lags are then not lost in its modulation), the
        delay of least MDL (:meth:`estimators._reflex.NormalEquations.best_delay`)."""
        ss = rx.scan_settings(self.settings)
        XI, Ph, W, first, last = data.XI, data.Ph, data.W, data.first, data.last
        N, R, LI = XI.shape
        M = Ph.shape[1]
        B = rx.basis(data.V, ss, data.scale)
        offset = B[first:last].reshape(-1, B.shape[-1]).mean(axis=0)
        B = B - offset
        d_lo = int(cands[0])
        XR = np.stack([rx.lag_matrix(B[:, r], d_lo, W - d_lo + 1) for r in range(R)], axis=1)[first:last]
        XR = XR * np.asarray(gain, float)[:, None, None, None]
        Z = np.concatenate([(XI[:, :, None, :] * Ph[:, None, :, None]).reshape(N * R, M * LI),
                            XR.reshape(N * R, -1)], axis=1)
        y = data.Yv.reshape(N * R)
        with blas_single_thread():
            G = Z.T @ Z
        ne = rx.NormalEquations(G=G, b=Z.T @ y, yy=float(y @ y), yy_centred=float(np.sum((y - y.mean()) ** 2)),
                                N=N * R, LI=M * LI, p=B.shape[-1], W=W, d_lo=d_lo, offset=offset)
        return ne.best_delay(cands)


def _on_record(x: np.ndarray, first: int, last: int, n: int) -> np.ndarray:
    """``x`` (the rows ``first ... last - 1``, along axis 0) on all ``n`` samples, held beyond its ends."""
    out = np.zeros((n,) + x.shape[1:])
    out[first:last] = x
    out[:first], out[last:] = x[0], x[-1]
    return out
