"""Parallel cascade (Kearney, Stein & Parameswaran 1997): intrinsic two-sided IRF plus a reflex Hammerstein pathway."""
from __future__ import annotations

import dataclasses
from typing import NamedTuple

import numpy as np

from jointbench.estimators import Estimator, register
from jointbench.estimators import _reflex as rx
from jointbench.estimators._twosided import (LagSettings, check_lengths, estimate_irf, fit_irf, irf_intervals,
                                             lag_samples, mdl_pseudo_inverse)
from jointbench.core.estimate import IRFEstimate, Prediction
from jointbench.core.errors import InputError
from jointbench.core.scores import vaf
from jointbench.core.schema import param
from jointbench.core.signal import Differentiate, velocity
from jointbench.core.types import Trial


class CascadeFit(NamedTuple):
    """The parallel-cascade iteration's result at one delay (:meth:`ParallelCascade._iterate`)."""

    a: np.ndarray              #: the static nonlinearity's coefficients (before :func:`estimators._reflex.finish`)
    h: np.ndarray              #: the reflex IRF
    iterations: int
    rss_intrinsic: float       #: the residual of the intrinsic IRF alone (the first iteration's), on the same rows
    kept_intrinsic: int        #: the directions that intrinsic IRF kept (its MDL parameters)


@dataclasses.dataclass(eq=False)
class ParallelCascadeEstimate(IRFEstimate):
    """The intrinsic two-sided IRF (an :class:`~jointbench.core.estimate.IRFEstimate`: ``lags``, ``h``, its
    intervals, :meth:`stiffness` = ``sum(h)``) and the reflex pathway: the velocity delayed by
    ``reflex_delay`` samples, through ``nonlinearity``, then the causal IRF ``reflex_h`` (lags
    ``reflex_delay ... reflex_delay + len(reflex_h) - 1``). ``reflex_h`` is None when the reflex pathway
    was not kept (the estimate is then the two-sided IRF alone).

    :meth:`predict` is the sum of both pathways; :meth:`intrinsic_torque` and :meth:`reflex_torque` are
    each alone. Given an angle only, they differentiate it (central differences); :meth:`prediction` of a
    trial takes the trial's velocity as the fit did (``differentiate``: :func:`jointbench.core.signal.velocity`).
    :attr:`vaf_total`, :attr:`vaf_intrinsic`, :attr:`vaf_reflex` are the VAFs of the measured torque by the
    whole model and by each pathway alone (the REKLAB toolbox's VAFT, VAFi, VAFr), in percent, on the samples
    both pathways reach (:attr:`rows`).
    """

    reflex_h: np.ndarray | None = None
    reflex_delay: int = 0
    nonlinearity: rx.StaticNonlinearity | None = None
    rows: tuple[int, int] = (0, 0)
    vaf_total: float = float("nan")
    vaf_intrinsic: float = float("nan")
    vaf_reflex: float = 0.0
    differentiate: Differentiate = "before_decimation"     #: where the fit took the velocity (its setting)

    def intrinsic_torque(self, u: np.ndarray) -> np.ndarray:
        """The intrinsic pathway's torque for the angle ``u`` (the two-sided IRF)."""
        return IRFEstimate.predict(self, u)

    def reflex_torque(self, u: np.ndarray, v: np.ndarray | None = None) -> np.ndarray:
        """The reflex pathway's torque for the angle ``u`` with its velocity ``v`` (default: central differences
        of ``u``); zeros without a reflex pathway."""
        u = np.asarray(u, float)
        if self.reflex_h is None:
            return np.zeros(len(u))
        v = rx.velocity(u, self.fs) if v is None else np.asarray(v, float)
        x = self.nonlinearity(v) - self.nonlinearity.offset
        return rx.lag_matrix(x, self.reflex_delay, len(self.reflex_h)) @ self.reflex_h

    def predict(self, u: np.ndarray, v: np.ndarray | None = None) -> np.ndarray:
        """Both pathways' torque for the angle ``u`` (its velocity ``v``: default, central differences of ``u``)."""
        return self.intrinsic_torque(u) + self.reflex_torque(u, v)

    def prediction(self, trial, index: int = 0) -> Prediction:
        """The torque (mean removed) against both pathways' prediction from the angle (mean removed) and its
        velocity as the fit took it, on the samples both pathways reach (:attr:`rows`)."""
        y = trial.output - np.mean(trial.output)
        yhat = self.predict(trial.input - np.mean(trial.input), velocity(trial, self.differentiate))
        used = np.zeros(len(y), bool)
        used[self.rows[0]:self.rows[1]] = True
        return Prediction(y, yhat, used, "torque (mean removed) against the intrinsic and reflex pathways' prediction "
                          f"from the angle (mean removed), samples {self.rows[0]} ... {self.rows[1] - 1}")

    def response_frame(self):
        """Both IRFs in long form: ``pathway, lag, lag_s, h`` (the intrinsic's ``h_lo``, ``h_hi``)."""
        import pandas as pd

        frame = super().response_frame().assign(pathway="intrinsic")
        if self.reflex_h is not None:
            lags = self.reflex_delay + np.arange(len(self.reflex_h))
            frame = pd.concat([frame, pd.DataFrame({"lag": lags, "lag_s": lags / self.fs, "h": self.reflex_h,
                                                    "pathway": "reflex"})], ignore_index=True)
        return frame

    def summary(self):
        out = super().summary()
        out.update({"vaf_total": self.vaf_total, "vaf_intrinsic": self.vaf_intrinsic, "vaf_reflex": self.vaf_reflex})
        return out


@register("parallel_cascade", tags=("lti", "nonparametric", "irf", "reflex"))
class ParallelCascade(Estimator):
    """Intrinsic and reflex stiffness by the iterative parallel-cascade procedure of Kearney et al. (1997).

    The torque is the sum of an intrinsic pathway, a two-sided IRF of the angle on lags ``-M1 ... M2``
    (:mod:`estimators._twosided`: least squares with the REKLAB toolbox's MDL pseudo-inverse), and a reflex
    pathway, a Hammerstein cascade of the delayed velocity (:mod:`estimators._reflex`). The procedure
    alternates: the intrinsic IRF is fitted to the torque minus the reflex pathway's output (zero at
    first), the reflex pathway to the torque minus the intrinsic output, until the total VAF improves by
    less than ``tolerance`` percentage points (or ``max_iter``). Without a fixed ``delay`` the delay is
    chosen first, every sample from ``delay_min`` to ``delay_max``: the joint least-squares fit of both
    pathways (the fixed point of the iteration for a fixed nonlinearity) with the reflex IRF on the lags
    from the delay to the end of ``reflex_window``, the delay of least minimum description length
    (:meth:`estimators._reflex.NormalEquations.best_delay`: the leading lags the data show to be zero).

    ``keep_reflex = 'mdl'`` keeps the reflex pathway only if it lowers the minimum description length
    ``RSS (1 + k ln N / N)`` against the intrinsic IRF alone on the same samples; otherwise the estimate
    is the two-sided IRF of the whole record (``irf2_ls`` with the same lags) and the reflex VAF is 0.

    Parameters
    ----------
    settings : Settings
        ``lag_before``, ``lag_after`` (s, default 0.04: the REKLAB toolbox's intrinsic IRF of +-40 ms),
        ``remove_mean``, ``pseudo_inverse`` (of the intrinsic IRF); the reflex pathway: ``delay`` (or
        ``delay_min``, ``delay_max``), ``reflex_window``, ``nonlinearity``, ``stretch``, ``order``; the
        iteration: ``max_iter``, ``tolerance``, ``keep_reflex``; ``differentiate``: the velocity taken before
        decimation (default) or after (:class:`estimators._reflex.VelocitySettings`).

    Notes
    -----
    Takes one record. Raises :class:`InputError` for a delay not shorter than the reflex lag window, a
    record not longer than the lags, or a still angle. Returns a :class:`ParallelCascadeEstimate`.

    References
    ----------
    Kearney, R. E., Stein, R. B. & Parameswaran, L. (1997). Identification of intrinsic and reflex
    contributions to human ankle stiffness dynamics. IEEE Trans. Biomed. Eng. 44(6), 493-504.
    Westwick, D. T. & Kearney, R. E. (2003). Identification of Nonlinear Physiological Systems, Sec. 8
    (parallel cascades); the REKLAB toolbox's ``PC_stiffnessID`` (decimation to 100 Hz, +-40 ms intrinsic IRF).
    """

    accepts = frozenset({"trial"})

    @dataclasses.dataclass(frozen=True)
    class Settings(rx.ReflexSettings, LagSettings):
        lag_before: float = param(0.04, unit="s", ge=0, doc="intrinsic IRF: anticipatory lags down to -M1")
        lag_after: float = param(0.04, unit="s", ge=0, doc="intrinsic IRF: causal lags up to M2")

    def _fit(self, trials: list[Trial]) -> ParallelCascadeEstimate:
        s = self.settings
        tr = trials[0]
        fs, n = tr.fs, tr.n
        m1, m2 = lag_samples(s, fs)
        check_lengths(self.name, [tr], m1, m2, s)
        u = tr.angle - tr.angle.mean()
        y = tr.torque - tr.torque.mean()
        v = velocity(tr, s.differentiate)
        rx.check_moving(self.name, v)
        scale = float(np.max(np.abs(v)))
        cands, W = rx.delays(self.name, s, fs)
        first, last = max(m2, W), n - m1
        rows = slice(first, last)
        N = last - first
        p = 1 if s.nonlinearity != "polynomial" else s.order
        LI = m1 + m2 + 1
        L = W - int(cands[0]) + 1
        if N < 2 * (LI + p * L):
            raise InputError(f"{self.name}: record '{tr.name}' ({n} samples, {n / fs:g} s) leaves {max(N, 0)} samples "
                             f"past the lags for {LI + p * L} unknowns ({LI} intrinsic lags, {p} x {L} reflex); use a "
                             f"longer record, shorter lags or a shorter reflex_window")
        ne = rx.NormalEquations.build(u, v, y, rows, m1, m2, cands, W, s, scale)
        if len(cands) == 1:
            d = int(cands[0])
        else:       # the delay is found with the scan's nonlinearity: for a polynomial pathway, the rectifier
            ss = rx.scan_settings(s)
            scan = ne if ss is s else rx.NormalEquations.build(u, v, y, rows, m1, m2, cands, W, ss, scale)
            d = scan.best_delay(cands)
        L = ne.length(d)
        cascade = self._iterate(ne, d, p, N)
        nl, h = rx.finish(cascade.a, cascade.h, s, scale, ne.offset)
        tqR = rx.lag_matrix(nl(v) - nl.offset, d, L) @ h
        seg = slice(first - m2, last + m1)        # the intrinsic IRF of the reflex-corrected torque, its rows
        part = tr.replace(angle=tr.angle[seg], torque=(y - tqR)[seg], time=tr.time[seg], truth=None, channels={})
        fit = fit_irf(self.name, [part], s, "ls", "valid")
        tqI = np.convolve(u, fit.h)[m1:m1 + n]
        rss = float(np.sum((y - tqI - tqR)[rows] ** 2))
        k_R = L + (p - 1 if p > 1 else 0)
        keep = (s.keep_reflex == "always"
                or rx.mdl(rss, fit.kept + k_R, N) < rx.mdl(cascade.rss_intrinsic, cascade.kept_intrinsic, N))
        info = {"reflex_delay": f"{d / fs * 1e3:g} ms" + ("" if len(cands) == 1 else
                                                           f" (best of {len(cands)}: {cands[0] / fs * 1e3:g} ... "
                                                           f"{cands[-1] / fs * 1e3:g} ms)"),
                "iterations": cascade.iterations, "nonlinearity": nl.describe()}
        if not keep:
            return self._intrinsic_alone(tr, u, y, d, info)
        info["reflex"] = "kept (MDL)" if s.keep_reflex == "mdl" else "kept (keep_reflex = always)"
        est = ParallelCascadeEstimate(lags=np.arange(-m1, m2 + 1), h=fit.h, fs=fs, time=tr.time, estimator=self.name,
                                      reflex_h=h, reflex_delay=d, nonlinearity=nl, rows=(first, last),
                                      vaf_total=vaf(y[rows], (tqI + tqR)[rows], undefined="nan"),
                                      vaf_intrinsic=vaf(y[rows], tqI[rows], undefined="nan"),
                                      vaf_reflex=vaf(y[rows], tqR[rows], undefined="nan"),
                                      differentiate=s.differentiate)
        est.fit_info = {**fit.info, **info}
        return est.with_intervals(lambda: irf_intervals(fit))

    def _iterate(self, ne: rx.NormalEquations, d: int, p: int, N: int) -> CascadeFit:
        """The parallel-cascade iteration at delay ``d`` on the normal equations ``ne`` of both pathways: the
        intrinsic IRF fitted to the torque minus the reflex pathway's output (zero at first), the Hammerstein
        cascade to the torque minus the intrinsic output, until the total VAF improves by less than
        ``tolerance`` percentage points (or ``max_iter``)."""
        s = self.settings
        L = ne.length(d)
        I, R = ne.intrinsic_cols, ne.reflex_cols(d)
        GII, GIR, GRR = ne.G[np.ix_(I, I)], ne.G[np.ix_(I, R)], ne.G[np.ix_(R, R)]
        bI, bR = ne.b[I], ne.b[R]
        lam, V = np.linalg.eigh(GII)
        lam, V = lam[::-1], V[:, ::-1]
        sv = np.sqrt(np.maximum(lam, 0.0))
        cR = np.zeros(len(R))
        best, it, rss_I, kept_I = -np.inf, 0, None, len(I)
        for it in range(1, s.max_iter + 1):
            b_eff = bI - GIR @ cR
            yy_eff = ne.yy - 2 * cR @ bR + cR @ GRR @ cR
            hI, kept = self._intrinsic(sv, V, b_eff, yy_eff, N)
            if rss_I is None:                      # the intrinsic IRF alone, on the same samples
                rss_I, kept_I = float(ne.yy - 2 * hI @ bI + hI @ GII @ hI), kept
            a, h = rx.hammerstein(GRR, bR - GIR.T @ hI, p, L)
            cR = np.outer(a, h).ravel()
            th = np.concatenate([hI, cR])
            Gs = ne.G[np.ix_(np.r_[I, R], np.r_[I, R])]
            total = 100.0 * (1.0 - float(ne.yy - 2 * th @ np.r_[bI, bR] + th @ Gs @ th) / ne.yy_centred)
            if total - best < s.tolerance:
                break
            best = total
        return CascadeFit(a=a, h=h, iterations=it, rss_intrinsic=rss_I, kept_intrinsic=kept_I)

    def _intrinsic_alone(self, tr: Trial, u: np.ndarray, y: np.ndarray, d: int, info: dict) -> ParallelCascadeEstimate:
        """The estimate without the reflex pathway: the two-sided IRF of the whole record (``irf2_ls`` with the
        same lags), reflex VAF 0."""
        s = self.settings
        n = tr.n
        m1, m2 = lag_samples(s, tr.fs)
        irf = estimate_irf(self.name, [tr], s, "ls", "valid", self.name)
        info["reflex"] = "not kept: it does not lower the MDL against the intrinsic IRF alone"
        tqI = irf.predict(u)
        sl = slice(m2, n - m1)
        est = ParallelCascadeEstimate(lags=irf.lags, h=irf.h, fs=tr.fs, time=tr.time, estimator=self.name,
                                      rows=(m2, n - m1), vaf_total=vaf(y[sl], tqI[sl], undefined="nan"),
                                      vaf_intrinsic=vaf(y[sl], tqI[sl], undefined="nan"), vaf_reflex=0.0,
                                      reflex_delay=d, differentiate=s.differentiate)
        est.fit_info = {**irf.fit_info, **info}
        return est.with_intervals(lambda: irf.intervals)

    def _intrinsic(self, sv: np.ndarray, V: np.ndarray, b: np.ndarray, yy: float, N: int) -> tuple[np.ndarray, int]:
        """The intrinsic IRF from its normal equations (``G = V diag(sv^2) V^T``): the MDL pseudo-inverse of
        :func:`estimators._twosided.mdl_pseudo_inverse` in the singular basis, or least squares."""
        # numerically null directions: the usual rank threshold, the number of lags times eps of the largest
        # singular value (the MDL pseudo-inverse applies its own, stricter one)
        usable = sv > len(sv) * np.finfo(float).eps * sv.max()
        c = np.where(usable, (V.T @ b) / np.where(usable, sv, 1.0), 0.0)
        if self.settings.pseudo_inverse == "mdl":
            h, kept = mdl_pseudo_inverse(sv, V, c, max(yy - float(c @ c), 0.0), N)
            return h, len(kept)
        return V[:, usable] @ (c[usable] / sv[usable]), int(usable.sum())
