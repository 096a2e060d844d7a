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
                                          lag_samples, one_blas_thread)
from jointbench.estimators.guarin import BasisKind, time_basis
from jointbench.core.ensemble import Ensemble
from jointbench.core.errors import InputError
from jointbench.core.estimate_tv import TVIRFEstimate
from jointbench.core.schema import param


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

    def reflex_torque(self, u: np.ndarray) -> np.ndarray:
        """The reflex pathway's torque for an angle ``u`` on the fitted time base (zeros without one)."""
        u = np.asarray(u, float)
        if self.reflex_h is None:
            return np.zeros(len(u))
        x = self.nonlinearity(rx.velocity(u, self.fs)) - self.nonlinearity.offset
        return self.reflex_gain * (rx.lag_matrix(x, self.reflex_delay, len(self.reflex_h)) @ self.reflex_h)

    def intrinsic_torque(self, u: np.ndarray) -> np.ndarray:
        return TVIRFEstimate.predict(self, u)

    def predict(self, u: np.ndarray) -> np.ndarray:
        return self.intrinsic_torque(u) + self.reflex_torque(u)

    def summary(self):
        out = super().summary()
        out.update({"vaf_total": self.vaf_total, "vaf_intrinsic": self.vaf_intrinsic, "vaf_reflex": self.vaf_reflex})
        return out


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
    Takes an ensemble (or one trial: an ensemble of one). Returns a :class:`TVCascadeEstimate`, valid on
    the samples both pathways' lags reach in every realization.

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
        n_basis: int = param(11, ge=1, doc="number of basis functions M")
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
        V = rx.velocity(U, fs)                                      # (n, R)
        rx.check_moving(self.name, V)
        scale = float(np.max(np.abs(V)))
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
        Phi = time_basis(s.basis, M, n, s.width)                   # (n, M)
        Ph = Phi[first:last]
        XI = sliding_window_view(np.concatenate([np.zeros((m2, R)), U, np.zeros((m1, R))]), LI, axis=0)[..., ::-1]
        XI = XI[first:last]                                         # (N, R, LI)
        Yv = Y[first:last]
        GI, bI_alone = basis_normal(XI, Yv, Ph)                      # bI_alone: the intrinsic pathway alone
        ss = float(np.sum((Yv - Yv.mean(axis=0)) ** 2))
        if len(cands) == 1:
            d = int(cands[0])
            fit = self._cascade(d, XI, Ph, GI, V, Yv, first, last, W, scale, ss)
        else:   # the delay with a constant gain, then once more with the gain the cascade found
            d = self._delay(XI, Ph, V, Yv, first, last, cands, W, scale, np.ones(N))
            fit = self._cascade(d, XI, Ph, GI, V, Yv, first, last, W, scale, ss)
            d2 = self._delay(XI, Ph, V, Yv, first, last, cands, W, scale, fit[2])
            if d2 != d:
                d, fit = d2, self._cascade(d2, XI, Ph, GI, V, Yv, first, last, W, scale, ss)
        a, h, g, tqI, tqR, cI, rss_I, it, offset = fit
        L = W - d + 1
        rss = float(np.sum((Yv - tqI - tqR) ** 2))
        k_I, k_R = M * LI, M + L + (p - 1 if p > 1 else 0)
        keep = s.keep_reflex == "always" or rx.mdl(rss, k_I + k_R, R * N) < rx.mdl(rss_I, k_I, R * N)
        if not keep:                                                # the intrinsic pathway alone, refitted
            cI = rx.solve_normal(GI, bI_alone, s.rcond).reshape(M, LI)
            tqI, tqR = np.einsum("trl,tm,ml->tr", XI, Ph, cI), np.zeros_like(Yv)
        nl, h = rx.finish(a, h, s, scale, offset) if keep else (None, None)
        gain = np.zeros(n)
        gain[first:last] = g
        gain[:first], gain[last:] = g[0], g[-1]
        valid = np.zeros(n, bool)
        valid[first:last] = True
        H = np.zeros((LI, n))
        H[:, first:last] = (Ph @ cI).T
        H[:, :first], H[:, last:] = H[:, first:first + 1], H[:, last - 1:last]
        vt = lambda yhat: 100.0 * (1.0 - float(np.sum((Yv - yhat) ** 2)) / ss)  # noqa: E731
        info = {"realizations": R, "basis": f"{M} {s.basis}", "reflex_delay": f"{d / fs * 1e3:g} ms",
                "iterations": it, "reflex": ("kept (MDL)" if s.keep_reflex == "mdl" else "kept (always)") if keep
                else "not kept: it does not lower the MDL against the intrinsic pathway alone"}
        if keep:
            info["nonlinearity"] = nl.describe()
        return TVCascadeEstimate(lags=np.arange(-m1, m2 + 1), h=H, fs=fs, time=ens.time, valid=valid,
                                 estimator=self.name, info=info, reflex_h=h if keep else None,
                                 reflex_gain=gain if keep else None, reflex_delay=d, nonlinearity=nl,
                                 vaf_total=vt(tqI + tqR), vaf_intrinsic=vt(tqI), vaf_reflex=vt(tqR) if keep else 0.0)

    def _cascade(self, d, XI, Ph, GI, V, Yv, first, last, W, scale, ss):
        """The parallel-cascade iteration at delay ``d``: returns the reflex pathway ``a, h, g``, both
        pathways' outputs, the intrinsic coefficients, the intrinsic-only residual, the iterations and the
        nonlinearity's offsets."""
        s = self.settings
        N, R, LI = XI.shape
        M = Ph.shape[1]
        L = W - d + 1
        B = rx.basis(V, s, scale)                                   # (n, R, p): not centred (see _reflex)
        p = B.shape[-1]
        offset = np.zeros(p)
        XR = np.stack([rx.lag_matrix(B[:, r], d, L) for r in range(R)], axis=1)[first:last]   # (N, R, p, L)
        a, h, g = np.ones(p), np.zeros(L), np.ones(N)
        tqR = np.zeros_like(Yv)
        best, it, rss_I = -np.inf, 0, None
        for it in range(1, s.max_iter + 1):
            bI = basis_rhs(XI, Yv - tqR, Ph)
            cI = rx.solve_normal(GI, bI, s.rcond).reshape(M, LI)
            tqI = np.einsum("trl,tm,ml->tr", XI, Ph, cI)
            if rss_I is None:
                rss_I = float(np.sum((Yv - tqI) ** 2))
            a, h, g, tqR = self._reflex(XR, Yv - tqI, Ph, a, h, g, it == 1)
            total = 100.0 * (1.0 - float(np.sum((Yv - tqI - tqR) ** 2)) / ss)
            if total - best < s.tolerance:
                break
            best = total
        return a, h, g, tqI, tqR, cI, rss_I, it, offset

    def _reflex(self, XR, Y, Ph, a, h, g, start: bool):
        """The reflex pathway ``g(t) sum_k h(k) N_a(v(t - d - k))`` fitted to ``Y`` (rows x R): alternately
        the cascade given the gain (normal equations of the products, :func:`estimators._reflex.hammerstein`)
        and the gain on the time basis given the cascade; returns ``a, h, g, output``.

        The nonlinearity's output is not centred before the gain: a rectified velocity has a mean, and a
        varying gain turns it into a slow torque (the reflex tone follows the gain), which is part of the
        pathway. Each realization's regressors are centred instead (the torque's mean is removed)."""
        s = self.settings
        N, R, p, L = XR.shape

        def centred(X):
            return X - X.mean(axis=0, keepdims=True)

        prev = np.inf
        for _ in range(10 if not start else 20):
            Xg = centred(XR * g[:, None, None, None]).reshape(N * R, p * L)
            G, b = Xg.T @ Xg, Xg.T @ Y.reshape(N * R)
            a, h = rx.hammerstein(G, b, p, L)
            z = np.einsum("trpl,p,l->tr", XR, a, h)                  # the cascade's output, gain 1
            Zf = centred(z[:, :, None] * Ph[:, None, :]).reshape(N * R, -1)
            e = rx.solve_normal(Zf.T @ Zf, Zf.T @ Y.reshape(N * R), s.rcond)
            g = Ph @ e
            mean_g = float(np.mean(g))
            if mean_g != 0:                                          # the cascade carries the mean gain
                g, h = g / mean_g, h * mean_g
            out = centred(g[:, None] * np.einsum("trpl,p,l->tr", XR, a, h))
            rss = float(np.sum((Y - out) ** 2))
            if prev - rss <= 1e-9 * max(rss, 1e-300):
                break
            prev = rss
        return a, h, g, out

    def _delay(self, XI, Ph, V, Yv, first, last, cands, W, scale, gain) -> int:
        """The delay of the joint fit of both pathways over every realization, the intrinsic IRF on the time
        basis (a time-invariant one would leave the variation of K in the residual and hide the reflex's
        first lags), the reflex IRF time-invariant on the lags ``d ... W`` scaled by ``gain(t)`` (1, or the
        gain of a first fit: a modulated reflex's small lags are then not lost in its modulation), the
        delay of least MDL (:meth:`estimators._reflex.NormalEquations.best_delay`)."""
        ss = rx.scan_settings(self.settings)
        N, R, LI = XI.shape
        M = Ph.shape[1]
        B = rx.basis(V, ss, scale)
        offset = B[first:last].reshape(-1, B.shape[-1]).mean(axis=0)
        B = B - offset
        d_lo = int(cands[0])
        XR = np.stack([rx.lag_matrix(B[:, r], d_lo, W - d_lo + 1) for r in range(R)], axis=1)[first:last]
        XR = XR * np.asarray(gain, float)[:, None, None, None]
        Z = np.concatenate([(XI[:, :, None, :] * Ph[:, None, :, None]).reshape(N * R, M * LI),
                            XR.reshape(N * R, -1)], axis=1)
        y = Yv.reshape(N * R)
        with one_blas_thread():
            G = Z.T @ Z
        ne = rx.NormalEquations(G=G, b=Z.T @ y, yy=float(y @ y), yy_centred=float(np.sum((y - y.mean()) ** 2)),
                                N=N * R, LI=M * LI, p=B.shape[-1], W=W, d_lo=d_lo, offset=offset)
        return ne.best_delay(cands)

