"""Parameter-varying IRF: a two-sided IRF whose coefficients are polynomials of a scheduling variable
(LPV, one trial)."""
from __future__ import annotations

import dataclasses
import math
from typing import TYPE_CHECKING, ClassVar

import numpy as np
from numpy.polynomial import chebyshev
from scipy import signal as sps

from jointbench.estimators import Estimator, register
from jointbench.estimators._reflex import RCOND
from jointbench.estimators._twosided import Lags, check_lengths, lag_samples, regressor
from jointbench.core.estimate import Estimate, Intervals, Prediction
from jointbench.core.errors import ConfigError, InputError
from jointbench.core.intervals import (LEVEL, contrast_dof, psd_pinv, psd_solve, segment_covariance, segment_shortfall,
                                       t_quantile)
from jointbench.core.schema import param
from jointbench.core.types import Trial

if TYPE_CHECKING:  # pragma: no cover
    import pandas as pd

#: derived scheduling variables (any other name is a recorded channel of the trial)
DERIVED = ("angle_slow", "angle")
#: the data must hold at least this many samples per unknown
SAMPLES_PER_UNKNOWN = 10
#: eigenvalues of the Gram matrix below this fraction of the largest are left out of its pseudo-inverse
GRAM_RCOND = 1e-12
#: points of the visited range where the degrees of freedom of K's band are worked out (:func:`stiffness_dof`)
DOF_POINTS = 101


def slow_part(angle: np.ndarray, fs: float, cutoff: float) -> np.ndarray:
    """The slow part of the angle: a 2nd-order Butterworth low-pass at ``cutoff`` run forwards and
    backwards (zero phase; the ends padded by reflection)."""
    if not cutoff < fs / 2:
        raise InputError(f"pv_irf: slow_cutoff = {cutoff:g} Hz is not below the Nyquist rate {fs / 2:g} Hz")
    sos = sps.butter(2, cutoff, fs=fs, output="sos")
    return sps.sosfiltfilt(sos, np.asarray(angle, float), padtype="even")


def schedule_of(name: str, trial: Trial, cutoff: float) -> tuple[np.ndarray, np.ndarray, float, str]:
    """``(s, u, reference, what)``: the scheduling variable, the IRF's input, the range the schedule's
    span is judged against, and a description. ``angle_slow``: the slow angle, the input is the angle
    minus it (the perturbation); ``angle``: the angle itself, the input its deviation from the mean; a
    channel of the trial: that channel, the input the angle's deviation from its mean."""
    a = trial.angle
    if name == "angle_slow":
        s = slow_part(a, trial.fs, cutoff)
        return s, a - s, float(np.ptp(a)), f"angle low-passed at {cutoff:g} Hz"
    if name == "angle":
        return a.copy(), a - a.mean(), float(np.ptp(a)), "angle"
    chans = getattr(trial, "channels", {}) or {}
    if name not in chans:
        known = ", ".join([*DERIVED, *chans]) or ", ".join(DERIVED)
        raise InputError(f"pv_irf: record '{trial.name}' has no channel '{name}' to schedule on; known: {known}")
    s = np.asarray(chans[name], float)
    return s, a - a.mean(), float(max(np.max(np.abs(s)), np.ptp(s))), f"channel '{name}'"


def checked_lags(name: str, trial: Trial, s) -> tuple[int, int]:
    """``(M1, M2)`` of the settings ``s`` at the trial's rate, after the checks every parameter-varying IRF makes
    of its one record: longer than the lags, and an angle that moves (one-line :class:`InputError`)."""
    m1, m2 = lag_samples(s, trial.fs)
    check_lengths(name, [trial], m1, m2, s)
    if not np.ptp(trial.angle) > 0:
        raise InputError(f"{name}: the angle of record '{trial.name}' is constant; nothing to identify")
    return m1, m2


def slow_edge(s, fs: float) -> int:
    """The samples at each end of a record where the slow angle (schedule ``angle_slow``) is the start-up of its
    low-pass filter rather than the movement: until the filter's transient has decayed to 1 %, ``ln(100) / (zeta
    2 pi slow_cutoff)`` seconds (the 2nd-order Butterworth's envelope ``exp(-zeta omega t)``, ``zeta = 1 /
    sqrt(2)``; 3.5 s at 0.3 Hz). There the slow angle is off by up to a few tenths of the movement's amplitude
    (0.12 rad on a 0.3 rad movement at 0.1 Hz) and the perturbation, the angle minus it, by as much: samples of
    large leverage in the wrong place of the schedule. 0 for the other schedules (not filtered)."""
    if s.schedule != "angle_slow":
        return 0
    return int(math.ceil(fs * math.log(100.0) / (2.0 * math.pi * s.slow_cutoff / math.sqrt(2.0))))


def visited_schedule(name: str, trial: Trial, s, rows: slice) -> tuple[np.ndarray, np.ndarray, float, float, str]:
    """``(sigma, u, lo, hi, what)``: the scheduling variable and the IRF's input (:func:`schedule_of` with the
    settings ``s``: ``schedule``, ``slow_cutoff``) and the range ``[lo, hi]`` the schedule visits on the fitted
    ``rows``.

    Raises
    ------
    InputError
        The schedule spans less than ``s.min_span`` of its range (one line)."""
    sig, x, reference, what = schedule_of(s.schedule, trial, s.slow_cutoff)
    lo, hi = float(np.min(sig[rows])), float(np.max(sig[rows]))
    span = hi - lo
    if not span >= s.min_span * reference or span <= 0:
        pct = 100.0 * span / reference if reference > 0 else 0.0
        raise InputError(f"{name}: the scheduling variable spans {pct:.2g} % of its range; "
                         f"a parameter-varying "
                         f"fit needs movement ({what} of record '{trial.name}')")
    return sig, x, lo, hi, what


def schedule_basis(name: str, sigma: np.ndarray, lo: float, hi: float, M: int,
                   offset: bool) -> tuple[np.ndarray, float]:
    """``(T1, cond)``: the Chebyshev polynomials ``T_0 ... T_M`` of ``sigma`` mapped from ``[lo, hi]`` to
    [-1, 1] (``(len(sigma), M + 1)``: the IRF's first ``M``, the offset's all), and the condition number of the
    columns used (``M + 1`` with an ``offset``, else ``M``), each scaled to unit norm.

    Raises
    ------
    InputError
        The schedule visits too few distinct values for the basis (condition number 1e6 or more; one line)."""
    T1 = chebyshev.chebvander(2.0 * (np.asarray(sigma, float) - lo) / (hi - lo) - 1.0, M)
    Tc = T1 if offset else T1[:, :M]
    cond = float(np.linalg.cond(Tc / np.sqrt(np.sum(Tc * Tc, axis=0))))
    if not cond < 1e6:
        raise InputError(f"{name}: the scheduling variable visits too few distinct values for {M} basis "
                         f"polynomials (condition number {cond:.2g}); the data cannot support that basis: lower "
                         f"n_basis")
    return T1, cond


def varying_irf_regressors(T: np.ndarray, u: np.ndarray, m1: int, m2: int, rows: slice) -> np.ndarray:
    """The regressors of the parameter-varying IRF on ``rows``: ``T_m(x(t)) u(t - k)``, column ``m L + k``
    (``T``: the basis on those rows, ``(N, M)``; lags ``-m1 ... m2``, zero outside the record)."""
    U = regressor(u, m1, m2, "zero")[0][rows]                                 # (N, L)
    N, M = T.shape
    return (T[:, :, None] * U[:, None, :]).reshape(N, M * U.shape[1])


@dataclasses.dataclass(eq=False)
class PVIRFEstimate(Estimate):
    """The parameter-varying IRF ``h(k, sigma) = sum_m c[m, k] T_m(x(sigma))`` (``x`` maps the visited range
    ``[lo, hi]`` of the scheduling variable to [-1, 1]) and the offset ``f(sigma) = sum_m d[m] T_m(x)``
    (``M + 1`` polynomials: one degree more than the IRF's, as the elastic torque integrates K).

    :meth:`stiffness_at` is ``K(sigma) = sum_k h(k, sigma)`` with its pointwise band :meth:`stiffness_band`;
    :meth:`stiffness` is K along the fitted record's schedule. ``h`` is not scaled by ``1/fs``.
    """

    lags: np.ndarray
    coef: np.ndarray          # (M, L)
    offset: np.ndarray        # (M + 1,)
    lo: float
    hi: float
    fs: float
    time: np.ndarray
    schedule: np.ndarray      # the scheduling variable at the fitted samples
    cov: np.ndarray | None    # covariance of coef.ravel() (M L)
    dof: int                  # the covariance's (segments - 1)
    schedule_name: str = "angle_slow"
    slow_cutoff: float = 1.0
    valid: np.ndarray | None = None
    estimator: str = "pv_irf"
    level: float = LEVEL
    #: the band's degrees of freedom at DOF_POINTS evenly spaced points of the visited range (:func:`stiffness_dof`)
    dof_of_x: np.ndarray | None = None

    def _x(self, sigma) -> np.ndarray:
        return 2.0 * (np.asarray(sigma, float) - self.lo) / (self.hi - self.lo) - 1.0

    def _T(self, sigma) -> np.ndarray:
        return chebyshev.chebvander(self._x(sigma), len(self.coef) - 1)

    def irf_at(self, sigma) -> np.ndarray:
        """The IRF at scheduling values ``sigma``: ``(L, len(sigma))``."""
        return (self._T(np.atleast_1d(sigma)) @ self.coef).T

    def stiffness_at(self, sigma) -> np.ndarray:
        """K(sigma) (N·m/rad) at scheduling values ``sigma`` (outside the visited range: extrapolated)."""
        return self._T(np.atleast_1d(sigma)) @ self.coef.sum(axis=1)

    def stiffness_band(self, sigma, level: float | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Pointwise ``level`` band of K(sigma) from the segment-robust covariance, with the t quantile of the
        degrees of freedom of K's variance at ``sigma`` (:attr:`dof_of_x`, interpolated; outside the visited
        range, its end's)."""
        k = self.stiffness_at(sigma)
        if self.cov is None:
            return np.full_like(k, np.nan), np.full_like(k, np.nan)
        T = self._T(np.atleast_1d(sigma))
        g = stiffness_gradient(T, self.coef.shape[1])
        se = np.sqrt(np.maximum(np.sum((g @ self.cov) * g, axis=1), 0.0))
        dof = (np.full(len(k), float(self.dof)) if self.dof_of_x is None else
               np.interp(self._x(np.atleast_1d(sigma)), np.linspace(-1.0, 1.0, len(self.dof_of_x)), self.dof_of_x))
        q = t_quantile(dof, self.level if level is None else level)
        return k - q * se, k + q * se

    def frequency_response(self, f: np.ndarray, t=None) -> np.ndarray:
        """The frozen response ``sum_k h(k, sigma(t)) exp(-j 2 pi f k / fs)`` at the schedule's value at
        time(s) ``t`` (``(len(t), len(f))``, or ``(len(f),)`` for a scalar); ``t = None``: at the schedule's
        mean over the fitted samples."""
        w = 2 * np.pi * np.atleast_1d(np.asarray(f, float)) / self.fs
        if t is None:
            sig = np.atleast_1d(np.mean(self.schedule if self.valid is None else self.schedule[self.valid]))
        else:
            sig = np.interp(np.atleast_1d(np.asarray(t, float)), self.time, self.schedule)
        H = (np.exp(-1j * np.outer(w, self.lags)) @ self.irf_at(sig)).T
        return H[0] if t is None or np.ndim(t) == 0 else H

    def stiffness(self, t) -> np.ndarray:
        sig = np.interp(np.asarray(t, float), self.time, self.schedule)
        out = self.stiffness_at(np.atleast_1d(sig))
        return out[0] if np.ndim(t) == 0 else out.reshape(np.shape(t))

    def _inputs(self, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        u = np.asarray(u, float)
        if len(u) != len(self.time):
            raise ValueError(f"{self.estimator}: predict needs an input on the fitted time base ({len(self.time)} "
                             f"samples), got {len(u)}")
        if self.schedule_name == "angle_slow":
            s = slow_part(u, self.fs, self.slow_cutoff)
            return s, u - s
        return self.schedule, u - u.mean()

    def predict(self, u: np.ndarray) -> np.ndarray:
        """Torque from the angle ``u`` on the fitted time base (the schedule recomputed from ``u`` when it is
        the slow angle, else the fitted record's)."""
        s, x = self._inputs(u)
        m1, m2 = -int(self.lags[0]), int(self.lags[-1])
        U = regressor(x, m1, m2, "zero")[0]
        T = chebyshev.chebvander(self._x(s), len(self.offset) - 1)
        return np.einsum("im,mk,ik->i", T[:, :len(self.coef)], self.coef, U) + T @ self.offset

    def prediction(self, trial, index: int = 0) -> Prediction:
        y = trial.output - np.mean(trial.output)
        used = np.ones(len(y), bool) if self.valid is None else self.valid.copy()
        return Prediction(y, self.predict(trial.input), used, "torque (mean removed) against the parameter-varying "
                          "IRF's prediction from the angle, on the samples whose lags lie in the record")

    def to_frame(self) -> "pd.DataFrame":
        import pandas as pd

        frame = pd.DataFrame({"time": self.time, "schedule": self.schedule, "stiffness": self.stiffness(self.time)})
        return self.add_interval_columns(frame)

    def response_frame(self, points: int = 101) -> "pd.DataFrame":
        """K over the visited range of the scheduling variable: ``schedule, stiffness`` (and its band)."""
        import pandas as pd

        grid = np.linspace(self.lo, self.hi, points)
        lo, hi = self.stiffness_band(grid)
        return pd.DataFrame({"schedule": grid, "stiffness": self.stiffness_at(grid), "stiffness_lo": lo,
                             "stiffness_hi": hi})

    def summary(self):
        out = super().summary()
        out["schedule"] = f"{self.schedule_name}: {self.lo:.4g} ... {self.hi:.4g}"
        out["basis"] = f"{len(self.coef)} Chebyshev polynomials x {len(self.lags)} lags"
        return out


@register("pv_irf", tags=("lpv", "nonparametric", "irf"))
class PVIRF(Estimator):
    """Parameter-varying two-sided IRF from one trial: K as a function of a scheduling variable.

    The torque is modelled as ``y(t) = sum_k h(k, sigma(t)) u(t - k) + f(sigma(t))`` with the IRF's
    coefficients and an offset expanded on Chebyshev polynomials of the scheduling variable ``sigma``
    (mapped to [-1, 1] over the range it visits): ``h(k, sigma) = sum_m c[m, k] T_m(x)``, ``f = sum_m d[m]
    T_m(x)`` (one degree more: the elastic torque integrates K), linear in the ``M L + M + 1`` unknowns, one
    least-squares problem over the record. With the
    default schedule ``angle_slow`` (the angle low-passed, zero phase, at ``slow_cutoff``) the IRF's input
    is the perturbation, the angle minus its slow part, and the offset takes the elastic torque of the
    slow movement (``P(sigma)``); the incremental stiffness ``K(sigma) = sum_k h(k, sigma)`` is then the
    slope of the torque-angle curve along the movement; the samples within the low-pass filter's start-up at
    either end (:func:`slow_edge`) are not fitted. Any recorded channel of the trial (``channels``) may be the
    schedule instead.

    The band of K(sigma) is pointwise (``level``), from a segment-robust covariance of the coefficients
    (contiguous segments of the record as clusters, neighbours' products half weighted, as the two-sided
    IRF's intervals, :func:`jointbench.core.intervals.segment_covariance`), with the t quantile of the
    degrees of freedom of K(sigma)'s variance (:func:`jointbench.core.intervals.contrast_dof`): fewer where
    few segments visit sigma.

    Parameters
    ----------
    settings : Settings
        ``lag_before``, ``lag_after`` (s, default 0.04), ``schedule`` ('angle_slow', 'angle' or a channel
        name), ``slow_cutoff`` (Hz), ``n_basis`` (M: polynomials of degree 0 ... M - 1), ``offset``,
        ``level``, ``min_span``.

    Notes
    -----
    Raises :class:`InputError` (one line) when the scheduling variable barely moves (its span below
    ``min_span`` of its range: the angle's range, or a channel's full scale), when the basis needs more
    unknowns than the record supports (``10`` samples per unknown), or when the schedule does not visit
    enough distinct values for ``n_basis`` polynomials. Returns a :class:`PVIRFEstimate`.

    References
    ----------
    Sobhani Tehrani, E. & Kearney, R. E. (2022). Parameter-varying parallel-cascade identification of ankle
    stiffness (IEEE Trans. Biomed. Eng.): the IRF expanded on Chebyshev polynomials of the scheduling
    variable (the REKLAB toolbox's ``pvirf``). Westwick, D. T. & Perreault, E. J. (2012), eq. 14 (the
    two-sided IRF).
    """

    accepts = frozenset({"trial"})

    @dataclasses.dataclass(frozen=True)
    class Settings(Lags):
        lag_before: float = param(0.04, unit="s", ge=0, doc="anticipatory lags down to -M1")
        lag_after: float = param(0.04, unit="s", ge=0, doc="causal lags up to M2")
        schedule: str = param("angle_slow", doc="scheduling variable: 'angle_slow', 'angle' or a channel of the trial")
        slow_cutoff: float = param(0.5, unit="Hz", gt=0,
                                doc="cutoff of the slow angle (zero-phase low-pass); above the "
                                                              "movement, below the perturbation")
        n_basis: int = param(4, ge=1, le=20, doc="Chebyshev polynomials of the schedule (degree 0 ... n_basis - 1)")
        offset: bool = param(True, doc="also expand an offset f(sigma) (the elastic torque of the slow movement)")
        level: float = param(LEVEL, gt=0, lt=1, doc="level of the pointwise band of K(sigma)")
        min_span: float = param(0.01, gt=0, lt=1, doc="the schedule must span at least this fraction of its range")

        #: the estimator the settings' messages name (a subclass's settings name their own)
        estimator: ClassVar[str] = "pv_irf"

        def __post_init__(self):
            """A ``slow_cutoff`` other than the default with a schedule that is not ``angle_slow`` would be
            accepted and have no effect (only the slow angle is low-passed): refused, naming both settings."""
            if self.schedule != "angle_slow" and self.slow_cutoff != type(self).__dataclass_fields__[
                    "slow_cutoff"].default:
                raise ConfigError(f"{self.estimator}: slow_cutoff = {self.slow_cutoff:g} Hz has no effect with "
                                  f"schedule '{self.schedule}' (it is the cutoff of the slow angle, schedule "
                                  f"'angle_slow'); remove slow_cutoff or schedule on 'angle_slow'")

    def _fit(self, trials: list[Trial]) -> PVIRFEstimate:
        s = self.settings
        tr = trials[0]
        fs, n = tr.fs, tr.n
        m1, m2 = checked_lags(self.name, tr, s)
        edge = slow_edge(s, fs)
        rows = slice(max(m2, edge), n - max(m1, edge))
        N = rows.stop - rows.start
        if N <= 0:
            raise InputError(f"{self.name}: record '{tr.name}' ({n / fs:g} s) is not longer than twice the start-up "
                             f"of the slow angle's filter ({edge / fs:.3g} s at each end, slow_cutoff = "
                             f"{s.slow_cutoff:g} Hz); use a longer record or a higher slow_cutoff")
        sig, x, lo, hi, what = visited_schedule(self.name, tr, s, rows)
        M, L = s.n_basis, m1 + m2 + 1
        unknowns = M * L + (M + 1 if s.offset else 0)
        if N < SAMPLES_PER_UNKNOWN * unknowns:
            most = max(1, (N // SAMPLES_PER_UNKNOWN - (1 if s.offset else 0)) // (L + (1 if s.offset else 0)))
            raise InputError(f"{self.name}: a basis of {M} polynomials x {L} lags{' + offsets' if s.offset else ''} = "
                             f"{unknowns} unknowns is larger than {N} samples support ({SAMPLES_PER_UNKNOWN} per "
                             f"unknown); lower n_basis (at most {most}) or the lags, or use a longer record")
        T1, cond = schedule_basis(self.name, sig[rows], lo, hi, M, s.offset)   # (N, M + 1): the offset's
        X = varying_irf_regressors(T1[:, :M], x, m1, m2, rows)
        if s.offset:
            X = np.hstack([X, T1])
        y = (tr.torque - tr.torque.mean())[rows]
        G = X.T @ X
        c = psd_solve(G, X.T @ y, RCOND)[0]
        e = y - X @ c
        Pg = psd_pinv(G, GRAM_RCOND)
        cov, dof = segment_covariance([(X, e)], Pg)
        coef = c[:M * L].reshape(M, L)
        valid = np.zeros(n, bool)
        valid[rows] = True
        est = PVIRFEstimate(lags=np.arange(-m1, m2 + 1), coef=coef, offset=c[M * L:] if s.offset else np.zeros(M + 1),
                            lo=lo, hi=hi, fs=fs, time=tr.time, schedule=sig,
                            cov=None if cov is None else cov[:M * L, :M * L], dof=dof, schedule_name=s.schedule,
                            slow_cutoff=s.slow_cutoff, valid=valid, estimator=self.name, level=s.level,
                            dof_of_x=None if cov is None else stiffness_dof(X, Pg, M, L))
        est.fit_info = {"schedule": f"{what}, {lo:.4g} ... {hi:.4g}", "unknowns": unknowns,
                        "condition": f"{cond:.3g}"}
        if cov is None:
            est.fit_info["intervals"] = "none: " + segment_shortfall([N], X.shape[1])
        return est.with_intervals(lambda: stiffness_intervals(est))


def stiffness_gradient(T: np.ndarray, L: int, width: int | None = None) -> np.ndarray:
    """``d K(sigma) / d coef`` for the Chebyshev polynomials ``T`` (n, M) of the schedule's values: ``T_m`` for
    each of ``coef[m, :]``'s ``L`` lags (``n, M L``), zero-padded to ``width`` columns (the other regressors)."""
    g = np.repeat(T, L, axis=1)
    return g if width is None else np.hstack([g, np.zeros((len(g), width - g.shape[1]))])


def stiffness_dof(X: np.ndarray, P: np.ndarray, M: int, L: int, scale: np.ndarray | None = None) -> np.ndarray:
    """The degrees of freedom of K(sigma)'s variance (:func:`jointbench.core.intervals.contrast_dof`) at
    :data:`DOF_POINTS` evenly spaced points of the visited range (mapped to [-1, 1]), for the regressors ``X``
    (the IRF's ``M L`` columns first) with Gram pseudo-inverse ``P``; ``scale``: ``X``'s columns are the
    regressors divided by it (the contrasts are divided alike)."""
    T = chebyshev.chebvander(np.linspace(-1.0, 1.0, DOF_POINTS), M - 1)
    a = stiffness_gradient(T, L, X.shape[1])
    return contrast_dof([X], P, a if scale is None else a / scale)


def stiffness_intervals(est: PVIRFEstimate) -> Intervals | None:
    """The pointwise band of K along the fitted record's schedule and over the visited range (101 points)."""
    if est.cov is None:
        return None
    lo_t, hi_t = est.stiffness_band(est.schedule)
    grid = np.linspace(est.lo, est.hi, 101)
    lo_g, hi_g = est.stiffness_band(grid)
    return Intervals(level=est.level, method=f"segment-robust covariance ({est.dof + 1} segments; t quantile of "
                     "K's Bell-McCaffrey degrees of freedom), pointwise",
                     bounds={"stiffness": (lo_t, hi_t)}, response={"stiffness": (lo_g, hi_g)})
