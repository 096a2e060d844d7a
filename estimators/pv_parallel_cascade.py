"""Parameter-varying parallel cascade: intrinsic K(sigma) as a parameter-varying two-sided IRF, and a reflex
pathway whose static nonlinearity varies with the scheduling variable, from one trial (LPV)."""
from __future__ import annotations

import dataclasses
import functools
from typing import ClassVar, Literal, NamedTuple

import numpy as np
from numpy.polynomial import chebyshev
from scipy import signal as sps

from jointbench.estimators import Estimator, register
from jointbench.estimators import _reflex as rx
from jointbench.estimators.pv_irf import (GRAM_RCOND, SAMPLES_PER_UNKNOWN, PVIRF, PVIRFEstimate, checked_lags,
                                          schedule_basis, slow_edge, stiffness_dof, stiffness_intervals,
                                          varying_irf_regressors, visited_schedule)
from jointbench.core.errors import InputError
from jointbench.core.estimate import Prediction
from jointbench.core.intervals import psd_pinv, psd_solve, segment_covariance, segment_press, segment_shortfall
from jointbench.core.schema import param
from jointbench.core.scores import vaf
from jointbench.core.types import Trial

#: the span of the reflex nonlinearity is measured on this many velocities over ``-v_max ... v_max``
NONLINEARITY_GRID = 201


def slow_motion(sigma: np.ndarray, fs: float) -> np.ndarray:
    """The slow movement's velocity and acceleration (central differences of the slow angle), ``(n, 2)``: the
    regressors of the torque its own viscosity and inertia take, which the IRF of the perturbation does not
    see."""
    v = rx.velocity(sigma, fs)
    return np.column_stack([v, rx.velocity(v, fs)])


def reflex_functions(v: np.ndarray, x: np.ndarray, s, scale: float, R: int) -> np.ndarray:
    """The reflex pathway's input functions ``phi_j(v(t)) T_r(x(t))`` (``(n, p R)``, column ``j R + r``): the
    nonlinearity's basis of the velocity (:func:`estimators._reflex.basis`: ``p`` functions) times the Chebyshev
    polynomials ``T_0 ... T_{R-1}`` of the mapped schedule ``x`` at the same sample (the nonlinearity varies with
    the schedule at the time of the stretch)."""
    Phi = rx.basis(v, s, scale)                                   # (n, p)
    T = chebyshev.chebvander(np.asarray(x, float), R - 1)         # (n, R)
    return (Phi[:, :, None] * T[:, None, :]).reshape(len(T), -1)


@dataclasses.dataclass(eq=False)
class PVParallelCascadeEstimate(PVIRFEstimate):
    """The parameter-varying IRF of the intrinsic pathway (a :class:`~estimators.pv_irf.PVIRFEstimate`: K(sigma),
    its pointwise band, the frozen response) with the torque of the slow movement's own velocity and
    acceleration, and the reflex pathway: the velocity, delayed by ``reflex_delay`` samples, through the
    schedule-varying nonlinearity ``N(v, sigma) = sum_{j,r} a[j, r] phi_j(v) T_r(x(sigma))``, then the causal
    IRF ``reflex_h`` (lags ``reflex_delay ... reflex_delay + len(reflex_h) - 1``). ``reflex_h`` is None when the reflex
    pathway was not kept (the estimate is then the intrinsic pathway alone).

    :meth:`predict` is the sum of both pathways; :meth:`intrinsic_torque` and :meth:`reflex_torque` are each
    alone; :meth:`reflex_gain_at` is the reflex's static gain along the schedule. :attr:`vaf_total`,
    :attr:`vaf_intrinsic` and :attr:`vaf_reflex` are the VAFs of the measured torque by the whole model and
    by each pathway alone, in percent, on the samples both pathways reach (:attr:`rows`).
    """

    slow_coef: np.ndarray | None = None        # of the slow movement's velocity and acceleration (angle_slow)
    reflex_h: np.ndarray | None = None
    reflex_delay: int = 0
    reflex_coef: np.ndarray | None = None      # a[j, r]: (p, R)
    reflex_settings: rx.PathwaySettings | None = None
    reflex_scale: float = 1.0                  # v_max (rad/s) of a polynomial nonlinearity's argument
    reflex_offset: np.ndarray | None = None    # the mean of each input function over the fitted rows (removed)
    rows: tuple[int, int] = (0, 0)
    vaf_total: float = float("nan")
    vaf_intrinsic: float = float("nan")
    vaf_reflex: float = 0.0
    estimator: str = "pv_parallel_cascade"

    def _schedule_of(self, u: np.ndarray) -> np.ndarray:
        return self._inputs(u)[0]

    def intrinsic_torque(self, u: np.ndarray) -> np.ndarray:
        """The intrinsic pathway's torque for the angle ``u`` on the fitted time base: the parameter-varying IRF
        and offset, and the torque of the slow movement's velocity and acceleration."""
        out = PVIRFEstimate.predict(self, u)
        if self.slow_coef is not None:
            out = out + slow_motion(self._schedule_of(u), self.fs) @ self.slow_coef
        return out

    def reflex_torque(self, u: np.ndarray) -> np.ndarray:
        """The reflex pathway's torque for the angle ``u`` on the fitted time base (zeros without one)."""
        u = np.asarray(u, float)
        if self.reflex_h is None:
            return np.zeros(len(u))
        F = reflex_functions(rx.velocity(u, self.fs), self._x(self._schedule_of(u)), self.reflex_settings,
                             self.reflex_scale, self.reflex_coef.shape[1]) - self.reflex_offset
        return rx.lag_matrix(F @ self.reflex_coef.ravel(), self.reflex_delay, len(self.reflex_h)) @ self.reflex_h

    def predict(self, u: np.ndarray) -> np.ndarray:
        return self.intrinsic_torque(u) + self.reflex_torque(u)

    def prediction(self, trial, index: int = 0) -> Prediction:
        """The torque (mean removed) against both pathways' prediction from the angle, on the samples both
        pathways reach (:attr:`rows`)."""
        y = trial.output - np.mean(trial.output)
        used = np.zeros(len(y), bool)
        used[self.rows[0]:self.rows[1]] = True
        return Prediction(y, self.predict(trial.input), used, "torque (mean removed) against the parameter-varying "
                          f"intrinsic and reflex pathways' prediction from the angle, samples {self.rows[0]} ... "
                          f"{self.rows[1] - 1}")

    def nonlinearity_at(self, v, sigma) -> np.ndarray:
        """``N(v, sigma)`` at velocities ``v`` (rad/s) and scheduling values ``sigma`` (broadcast), its mean
        over the fitted rows not removed."""
        v, sigma = np.broadcast_arrays(np.asarray(v, float), np.asarray(sigma, float))
        F = reflex_functions(v.ravel(), self._x(sigma.ravel()), self.reflex_settings, self.reflex_scale,
                             self.reflex_coef.shape[1])
        return (F @ self.reflex_coef.ravel()).reshape(v.shape)

    def reflex_gain_at(self, sigma) -> np.ndarray:
        """The reflex pathway's static gain at scheduling values ``sigma`` (N·m per rad/s): ``sum(reflex_h)``
        times the secant slope of ``N(., sigma)`` from 0 to ``v_max`` of stretch (for the rectifier and the
        linear pathway its slope, exactly); NaN without a reflex pathway."""
        sigma = np.atleast_1d(np.asarray(sigma, float))
        if self.reflex_h is None:
            return np.full(sigma.shape, np.nan)
        vmax = self.reflex_scale * (1.0 if self.reflex_settings.stretch == "positive" else -1.0)
        slope = (self.nonlinearity_at(vmax, sigma) - self.nonlinearity_at(0.0, sigma)) / abs(vmax)
        return slope * float(np.sum(self.reflex_h))

    def response_frame(self):
        """K over the visited range of the schedule (``schedule, stiffness`` and its band) and, with a reflex
        pathway, its static gain there (``reflex_gain``)."""
        frame = super().response_frame()
        if self.reflex_h is not None:
            frame["reflex_gain"] = self.reflex_gain_at(frame["schedule"].to_numpy())
        return frame

    def summary(self):
        out = super().summary()
        out.update({"vaf_total": self.vaf_total, "vaf_intrinsic": self.vaf_intrinsic, "vaf_reflex": self.vaf_reflex})
        if self.reflex_h is not None:
            g = self.reflex_gain_at(np.linspace(self.lo, self.hi, 5))
            out["reflex"] = (f"delay {self.reflex_delay / self.fs * 1e3:g} ms, {len(self.reflex_h)} lags; static gain "
                             + ", ".join(f"{x:.3g}" for x in g) + f" N.m.s/rad at 5 points of {self.lo:.4g} ... "
                             f"{self.hi:.4g}")
        return out


@register("pv_parallel_cascade", tags=("lpv", "nonparametric", "irf", "reflex"))
class PVParallelCascade(Estimator):
    """Parameter-varying parallel cascade from one trial: intrinsic K(sigma) and a reflex pathway that varies
    with the scheduling variable (Sobhani Tehrani & Kearney 2022).

    The torque is modelled as the sum of

    * the intrinsic pathway, :mod:`estimators.pv_irf`'s model: a two-sided IRF whose coefficients are
      Chebyshev polynomials of the schedule, ``sum_k h(k, sigma(t)) u(t - k)`` on the lags ``-M1 ... M2``,
      and the offset ``f(sigma)``; with the schedule ``angle_slow`` (``u`` the perturbation: the angle minus
      its slow part) also ``B_s sigma' + I_s sigma''``, the torque of the slow movement's own velocity and
      acceleration, which the IRF of the perturbation does not see (``slow_terms``; without them the reflex's
      regressors, which carry the slow velocity, take that torque and lend it to K: about 1 % of K on the
      ``lpv`` study's ankle);
    * the reflex pathway, a parameter-varying Hammerstein cascade: the joint velocity ``v`` (central
      differences of the whole angle: the stretch the muscle feels), delayed by ``d`` samples, through the
      static nonlinearity ``N(v, sigma) = sum_{j,r} a[j, r] phi_j(v) T_r(x(sigma))`` (``phi``: the half-wave
      rectifier of the stretch velocity, the velocity, or a polynomial, :func:`estimators._reflex.basis`;
      ``T_r``: ``reflex_basis`` Chebyshev polynomials of the schedule at the time of the stretch), then a
      causal IRF ``h_R`` on the lags ``d ... W`` (``W``: ``reflex_window``) that does not vary with the
      schedule (the reflex dynamics Sobhani Tehrani & Kearney found invariant with ankle position), expanded on
      ``laguerre_order + 1`` discrete Laguerre functions of the lag from ``d`` (:func:`laguerre`, as the REKLAB
      toolbox's ``nppv-pc``: its demo's order 8 and ``alfa`` 0.5 at 100 Hz, a time constant of 28.9 ms; the
      unknowns do not grow with the sampling rate)::

          T_R(t) = sum_{k=d}^{W} h_R(k) N(v(t - k), sigma(t - k)),    h_R(k) = sum_q c_q f_q(k - d)

    Identification, as the REKLAB toolbox's ``nppv-pc`` method (``@pvpc``): the reflex pathway's products
    ``a[j, r] c_q`` are linear regressors, and one least-squares problem over both pathways gives the
    intrinsic coefficients, the orthogonal projection of the torque onto the intrinsic regressors after the
    reflex regressors are accounted for (what the reflex can explain is never read as stiffness); the
    reflex's Hammerstein cascade ``(a, h_R)`` is then fitted to the torque the intrinsic pathway leaves
    (:func:`estimators._reflex.hammerstein`: the rank-one approximation of the products, then alternating
    least squares). The band of K(sigma) is the joint fit's, pointwise, from its segment-robust covariance
    (:func:`jointbench.core.intervals.segment_covariance`, the one segment rule, as :mod:`estimators.pv_irf`),
    with a t quantile: it counts the reflex's unknowns. Without a fixed ``delay`` the delay is the candidate
    (every sample of ``delay_min ... delay_max``) of least minimum description length of the joint fit; with
    Laguerre functions, which start at their largest, it is where the fitted IRF starts rather than the
    transport delay.
    ``keep_reflex = 'cv'`` (the default) keeps the reflex pathway only when the joint fit predicts the
    record's segments left out of it better than the intrinsic pathway alone (blocked cross-validation on
    the segments of the covariance, :func:`jointbench.core.intervals.segment_press`); ``'mdl'``, the REKLAB
    toolbox's rule, when it lowers the minimum description length ``RSS (1 + k ln N / N)``. Otherwise K(sigma)
    and its band are the intrinsic pathway's alone. The MDL counts each regressor as one degree of freedom of
    white noise and takes no account of the delay search: on issue 33's narrow-band record, with no reflex and
    torque noise low-passed at 30 Hz, it kept a reflex in 19 of 30 seeds at 20 ms lags (67 of 100), the
    cross-validation in 1 of 30 (0 of 30 at 40 ms), and the kept spurious pathway widened K's error beyond its
    band (6 of 67 misses against 2 of 33).

    Parameters
    ----------
    settings : Settings
        The intrinsic pathway's (as ``pv_irf``): ``lag_before``, ``lag_after``, ``schedule``, ``slow_cutoff``,
        ``n_basis``, ``offset``, ``level``, ``min_span``; ``slow_terms``; the reflex pathway's: ``delay`` (or
        ``delay_min``, ``delay_max``), ``reflex_window``, ``nonlinearity``, ``stretch``, ``order``,
        ``reflex_basis``, ``laguerre_order``, ``laguerre_time_constant``; ``keep_reflex``.

    Notes
    -----
    Takes one record. Raises :class:`InputError` (one line) for a schedule that barely moves, a basis larger
    than the record supports (:data:`estimators.pv_irf.SAMPLES_PER_UNKNOWN` samples per unknown of the joint
    fit), a delay not shorter than the reflex window, or a still angle. Returns a
    :class:`PVParallelCascadeEstimate`.

    The velocity is differentiated at the record's rate. The reflex the data show responds to the velocity
    of the whole movement, rectified at the muscle; the rectified velocity of a record at 100 Hz lacks what
    the velocity holds above the record's band and folds the rectifier's harmonics back into it. On the
    ``lpv`` study's ankle (a PRALDS smoothed at 20 Hz: 3.4 % of the velocity's power above 40 Hz) K(theta) is
    off by -1.2 % of K at 100 Hz and -0.2 % at 200 Hz, noise-free, and by +0.2 % at 100 Hz with the rectified
    velocity computed at 1 kHz and decimated (what remains: the Laguerre functions' approximation of the
    reflex IRF); the band holds the sampling error only.

    References
    ----------
    Sobhani Tehrani, E. & Kearney, R. E. (2022). Non-parametric nonlinear parameter-varying parallel-cascade
    identification of dynamic joint stiffness. IEEE Trans. Biomed. Eng. (doi 10.1109/TBME.2022.3217143; its
    abstract: the PV IRF of intrinsic stiffness, the PV static nonlinearity and PV linear element of the
    reflex pathway, reflex dynamics invariant with position); the REKLAB toolbox's ``@pvpc`` class
    (``pcasc_lpv_laguerre``: the orthogonal projection, then the PV Hammerstein on the reflex torque).
    Kearney, R. E., Stein, R. B. & Parameswaran, L. (1997), IEEE Trans. Biomed. Eng. 44(6), 493-504 (the
    parallel cascade). Westwick, D. T. & Kearney, R. E. (2003), Identification of Nonlinear Physiological
    Systems, Sec. 6.2 (Hammerstein cascades). Marmarelis, V. Z. (1993), Ann. Biomed. Eng. 21(6), 573-589
    (Laguerre expansions).
    """

    accepts = frozenset({"trial"})

    @dataclasses.dataclass(frozen=True)
    class Settings(rx.PathwaySettings, PVIRF.Settings):
        estimator: ClassVar[str] = "pv_parallel_cascade"

        reflex_basis: int = param(3, ge=1, le=10, doc="Chebyshev polynomials of the schedule in the reflex "
                                                      "nonlinearity (1: a reflex that does not vary with it)")
        laguerre_order: int = param(8, ge=1, le=16, doc="the reflex IRF: Laguerre functions of order 0 ... this")
        laguerre_time_constant: float = param(0.0289, unit="s", gt=0, doc="the decay time constant of the "
                                                                          "Laguerre functions' pole")
        slow_terms: bool = param(True, doc="with schedule angle_slow: also fit the torque of the slow movement's "
                                           "velocity and acceleration")
        keep_reflex: Literal["cv", "mdl", "always"] = param(
            "cv", doc="'cv': keep the reflex pathway only when it predicts left-out segments of the record better; "
                      "'mdl': only when it lowers the minimum description length (the REKLAB toolbox's rule); "
                      "'always'")

    def _fit(self, trials: list[Trial]) -> PVParallelCascadeEstimate:
        s = self.settings
        tr = trials[0]
        fs, n = tr.fs, tr.n
        m1, m2 = checked_lags(self.name, tr, s)
        u = tr.angle - tr.angle.mean()
        v = rx.velocity(u, fs)
        rx.check_moving(self.name, v)
        cands, W = rx.delays(self.name, s, fs)
        edge = slow_edge(s, fs)
        first, last = max(m2, W, edge), n - max(m1, edge)
        rows = slice(first, last)
        N = last - first
        if N <= 0:
            raise InputError(f"{self.name}: record '{tr.name}' ({n / fs:g} s) is not longer than the reflex window "
                             f"({s.reflex_window:g} s), the intrinsic lags and the start-up of the slow angle's filter "
                             f"({edge / fs:.3g} s at each end); use a longer record")
        sig, x, lo, hi, what = visited_schedule(self.name, tr, s, rows)
        M, LI, R = s.n_basis, m1 + m2 + 1, s.reflex_basis
        p = (s.order if s.nonlinearity == "polynomial" else 1) * R
        slow = s.slow_terms and s.schedule == "angle_slow"
        n_int = M * LI + (M + 1 if s.offset else 0) + (2 if slow else 0)
        Q = s.laguerre_order + 1
        unknowns = n_int + p * Q
        if N < SAMPLES_PER_UNKNOWN * unknowns:
            raise InputError(f"{self.name}: {n_int} intrinsic unknowns and {p} x {Q} reflex ones ({unknowns}) are "
                             f"more than {N} samples support ({SAMPLES_PER_UNKNOWN} per unknown); lower n_basis, "
                             f"reflex_basis or laguerre_order, or use a longer record")
        T1, cond = schedule_basis(self.name, sig[rows], lo, hi, M, s.offset)
        parts = [varying_irf_regressors(T1[:, :M], x, m1, m2, rows)]
        if s.offset:
            parts.append(T1)
        if slow:
            parts.append(slow_motion(sig, fs)[rows])
        XI = np.hstack(parts)
        xs = 2.0 * (sig - lo) / (hi - lo) - 1.0
        scale = float(np.max(np.abs(v)))
        y = (tr.torque - tr.torque.mean())[rows]
        pole = float(np.exp(-1.0 / (fs * s.laguerre_time_constant)))
        design = _Design(XI, y, rows, W, Q, pole)
        F, offset = design.functions(v, xs, s, scale, R)
        if len(cands) == 1:
            d = int(cands[0])
        else:        # the delay is found with the scan's nonlinearity: for a polynomial pathway, the rectifier
            ss = rx.scan_settings(s)
            d = design.best_delay(cands, F if ss is s else design.functions(v, xs, ss, scale, R)[0])
        XR, Lg = design.reflex_regressors(F, d)
        joint = design.solve(XR)
        alone = design.solve(XR[:, :0])
        designs = _Designs(XI, XR)
        keep, rule = keep_reflex(s.keep_reflex, designs, y, joint, alone)
        fit = joint if keep else alone
        cov, dof, dof_of_x = _covariance(designs.joint if keep else designs.alone, y, fit.c, M, LI)
        cI = fit.c[:n_int]
        info = {"schedule": f"{what}, {lo:.4g} ... {hi:.4g}", "unknowns": len(fit.c), "condition": f"{cond:.3g}",
                "reflex_delay": f"{d / fs * 1e3:g} ms" + ("" if len(cands) == 1 else
                                                           f" (best of {len(cands)}: {cands[0] / fs * 1e3:g} ... "
                                                           f"{cands[-1] / fs * 1e3:g} ms)"),
                "reflex_irf": f"{Q} Laguerre functions (time constant {s.laguerre_time_constant * 1e3:.3g} ms, pole "
                              f"{pole:.3g}) on the lags {d / fs * 1e3:g} ... {W / fs * 1e3:g} ms"}
        tqI = XI @ cI
        common = dict(lags=np.arange(-m1, m2 + 1), coef=cI[:M * LI].reshape(M, LI),
                      offset=cI[M * LI:M * LI + M + 1] if s.offset else np.zeros(M + 1), lo=lo, hi=hi, fs=fs,
                      time=tr.time, schedule=sig, cov=None if cov is None else cov[:M * LI, :M * LI], dof=dof,
                      dof_of_x=dof_of_x,
                      schedule_name=s.schedule, slow_cutoff=s.slow_cutoff, valid=_mask(n, rows), estimator=self.name,
                      level=s.level, slow_coef=cI[-2:] if slow else None, rows=(first, last),
                      vaf_intrinsic=vaf(y, tqI, undefined="nan"))
        if not keep:
            info["reflex"] = (f"not kept: it does not lower the "
                              f"{'error predicting left-out segments (CV)' if rule == 'CV' else 'MDL'} against the "
                              f"intrinsic pathway alone")
            est = PVParallelCascadeEstimate(**common, vaf_total=vaf(y, tqI, undefined="nan"), vaf_reflex=0.0,
                                            reflex_delay=d)
        else:
            G_RR, G_RI = XR.T @ XR, XR.T @ XI
            a, cq = rx.hammerstein(G_RR, XR.T @ y - G_RI @ cI, p, Q)
            a, h = _normalized(a, Lg @ cq, s, scale, xs[rows], R)
            tqR = rx.lag_matrix(F @ a, d, len(h))[rows] @ h
            info["reflex"] = f"kept ({rule})"
            est = PVParallelCascadeEstimate(**common, vaf_total=vaf(y, tqI + tqR, undefined="nan"),
                                            vaf_reflex=vaf(y, tqR, undefined="nan"), reflex_h=h, reflex_delay=d,
                                            reflex_coef=a.reshape(-1, R), reflex_settings=s, reflex_scale=scale,
                                            reflex_offset=offset)
        if cov is None:
            info["intervals"] = "none: " + segment_shortfall([N], len(fit.c))
        est.fit_info = info
        return est.with_intervals(lambda: stiffness_intervals(est))


class _Fit(NamedTuple):
    """A least-squares fit of the intrinsic regressors and some reflex ones (:meth:`_Design.solve`)."""

    c: np.ndarray       #: the coefficients
    rss: float          #: the residual sum of squares


def laguerre(L: int, Q: int, pole: float) -> np.ndarray:
    """The first ``Q`` discrete Laguerre functions on ``L`` lags, ``(L, Q)``: the impulse responses of
    ``sqrt(1 - a^2) / (1 - a z^-1) ((z^-1 - a) / (1 - a z^-1))^q`` (``a`` the pole, ``q = 0 ... Q - 1``),
    orthonormal over the infinite lag axis; Marmarelis' functions of parameter ``alpha = a^2``.

    References
    ----------
    Marmarelis, V. Z. (1993). Identification of nonlinear biological systems using Laguerre expansions of
    kernels. Ann. Biomed. Eng. 21(6), 573-589, eq. 11 (the functions) and their generating filters; the REKLAB
    toolbox's ``laguerre`` (its ``alfa`` is Marmarelis' ``alpha``).
    """
    impulse = np.zeros(L)
    impulse[0] = 1.0
    out = [sps.lfilter([np.sqrt(1.0 - pole * pole)], [1.0, -pole], impulse)]
    for _ in range(Q - 1):
        out.append(sps.lfilter([-pole, 1.0], [1.0, -pole], out[-1]))
    return np.column_stack(out)


class _Design:
    """The regressors of both pathways on the fitted rows: the intrinsic ones ``XI`` (fixed), and the reflex
    pathway's for a delay ``d``: each input function (:func:`reflex_functions`, its mean over the rows removed)
    delayed by ``d`` and filtered by the Laguerre functions on the lags ``0 ... W - d`` (column ``j Q + q``)."""

    def __init__(self, XI: np.ndarray, y: np.ndarray, rows: slice, W: int, Q: int, pole: float):
        self.XI, self.y, self.rows, self.W, self.Q, self.pole = XI, y, rows, W, Q, pole
        self.G_II, self.b_I, self.yy = XI.T @ XI, XI.T @ y, float(y @ y)

    def functions(self, v: np.ndarray, xs: np.ndarray, s, scale: float, R: int) -> tuple[np.ndarray, np.ndarray]:
        """The reflex input functions with their mean over the rows removed, and that mean."""
        F = reflex_functions(v, xs, s, scale, R)
        offset = F[self.rows].mean(axis=0)
        return F - offset, offset

    def reflex_regressors(self, F: np.ndarray, d: int) -> tuple[np.ndarray, np.ndarray]:
        """``(XR, Lg)``: the reflex regressors for delay ``d`` on the rows, and the Laguerre functions (lags ``d ...
        W``) they were filtered by."""
        L = self.W - d + 1
        Lg = laguerre(L, self.Q, self.pole)
        XR = rx.lag_matrix(F, d, L)[self.rows] @ Lg                # (N, p, Q)
        return XR.reshape(len(XR), -1), Lg

    def solve(self, XR: np.ndarray) -> _Fit:
        """Least squares on the intrinsic regressors and ``XR`` (from the normal equations,
        :func:`jointbench.core.intervals.psd_solve`)."""
        G_RI = XR.T @ self.XI
        G = np.block([[self.G_II, G_RI.T], [G_RI, XR.T @ XR]])
        b = np.concatenate([self.b_I, XR.T @ self.y])
        c = psd_solve(G, b, rx.RCOND)[0]
        return _Fit(c, max(self.yy - 2.0 * float(c @ b) + float(c @ G @ c), 0.0))

    def best_delay(self, cands: np.ndarray, F: np.ndarray) -> int:
        """The candidate delay of least minimum description length ``RSS (1 + k ln N / N)`` of the joint fit of
        both pathways (:func:`estimators._reflex.mdl`)."""
        N = len(self.y)
        scores = []
        for d in cands:
            XR = self.reflex_regressors(F, int(d))[0]
            scores.append(rx.mdl(self.solve(XR).rss, self.XI.shape[1] + XR.shape[1], N))
        return int(cands[int(np.argmin(scores))])


class _Scaled(NamedTuple):
    """Regressors ``X``, the same with each column scaled to unit norm (``Xs = X / scale``: the intrinsic, offset
    and reflex columns differ by orders of magnitude), and the pseudo-inverse ``P`` of ``Xs``' Gram matrix."""

    X: np.ndarray
    Xs: np.ndarray
    scale: np.ndarray
    P: np.ndarray


def _scaled(X: np.ndarray) -> _Scaled:
    scale = np.sqrt(np.maximum(np.sum(X * X, axis=0), 1e-300))
    Xs = X / scale
    return _Scaled(X, Xs, scale, psd_pinv(Xs.T @ Xs, GRAM_RCOND))


class _Designs:
    """Both pathways' regressors (``joint``: the intrinsic ``XI`` then the reflex ``XR``) and the intrinsic
    pathway's alone, each scaled once, when first needed (:func:`keep_reflex` and :func:`_covariance` share them)."""

    def __init__(self, XI: np.ndarray, XR: np.ndarray):
        self.XI, self.XR = XI, XR

    @functools.cached_property
    def joint(self) -> _Scaled:
        return _scaled(np.hstack([self.XI, self.XR]))

    @functools.cached_property
    def alone(self) -> _Scaled:
        return _scaled(self.XI)


def keep_reflex(how: str, designs: _Designs, y: np.ndarray, joint: "_Fit", alone: "_Fit") -> tuple[bool, str]:
    """Whether to keep the reflex pathway, and the rule that decided ('CV', 'MDL', for the summary); ``joint`` and
    ``alone`` the fits of ``designs.joint`` and ``designs.alone``. ``'cv'``: when the joint fit predicts the
    segments it was not fitted on better than the intrinsic pathway alone
    (:func:`jointbench.core.intervals.segment_press`, both on the joint fit's segments); with too few segments
    for it, as ``'mdl'``. ``'mdl'``: when it lowers the minimum description length ``RSS (1 + k ln N / N)`` (the
    REKLAB toolbox's rule). ``'always'``."""
    if how == "always":
        return True, "keep_reflex = always"
    columns = designs.XI.shape[1] + designs.XR.shape[1]
    if how == "cv":
        cv_joint, cv_alone = _press(designs.joint, y, joint.c, columns), _press(designs.alone, y, alone.c, columns)
        if np.isfinite(cv_joint) and np.isfinite(cv_alone):
            return bool(cv_joint < cv_alone), "CV"
    N = len(y)
    return bool(rx.mdl(joint.rss, columns, N) < rx.mdl(alone.rss, designs.XI.shape[1], N)), "MDL"


def _press(d: _Scaled, y: np.ndarray, c: np.ndarray, columns: int) -> float:
    """The leave-one-segment-out prediction error of the fit ``c`` of ``d.X`` to ``y``
    (:func:`jointbench.core.intervals.segment_press`, in the scaled columns; segments as for ``columns``
    regressors)."""
    return segment_press([(d.Xs, y - d.X @ c)], d.P, columns)


def _covariance(d: _Scaled, y: np.ndarray, c: np.ndarray, M: int,
                L: int) -> tuple[np.ndarray | None, int, np.ndarray | None]:
    """The segment-robust covariance of the coefficients ``c`` of the regressors ``d.X`` fitted to ``y``
    (:func:`jointbench.core.intervals.segment_covariance`), computed in the scaled columns and scaled back; its
    degrees of freedom; and those of K(sigma)'s variance over the visited range
    (:func:`estimators.pv_irf.stiffness_dof`, the IRF's ``M L`` columns first)."""
    cov, dof = segment_covariance([(d.Xs, y - d.X @ c)], d.P)
    if cov is None:
        return None, dof, None
    return cov / np.outer(d.scale, d.scale), dof, stiffness_dof(d.Xs, d.P, M, L, d.scale)


def _normalized(a: np.ndarray, h: np.ndarray, s, scale: float, xs: np.ndarray, R: int) -> tuple[np.ndarray, np.ndarray]:
    """Resolve the cascade's scale: the nonlinearity spans over ``-v_max ... v_max``, on average over the
    schedule's fitted values ``xs`` (mapped), as much as a half-wave rectifier does (``v_max``), so that
    ``h_R`` carries the pathway's mean gain (N·m per rad/s); and ``h_R`` sums to >= 0."""
    grid = np.linspace(-scale, scale, NONLINEARITY_GRID)
    at = np.quantile(xs, np.linspace(0.0, 1.0, 21))
    spans = [np.ptp(reflex_functions(grid, np.full(len(grid), x), s, scale, R) @ a) for x in at]
    span = float(np.mean(spans))
    k = scale / span if span > 0 else 1.0
    a, h = a * k, h / k
    if np.sum(h) < 0:
        a, h = -a, -h
    return a, h


def _mask(n: int, rows: slice) -> np.ndarray:
    out = np.zeros(n, bool)
    out[rows] = True
    return out
