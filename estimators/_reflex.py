"""Shared pieces of the parallel-cascade estimators: the reflex pathway as a Hammerstein cascade.

Private module (the leading underscore keeps it out of the estimator registry). Used by
:mod:`estimators.parallel_cascade` (one record), :mod:`estimators.parallel_cascade_tv` (an ensemble,
time-varying) and :mod:`estimators.pv_parallel_cascade` (one record, parameter-varying: the pathway's settings,
:class:`PathwaySettings`, without the iteration's).

The reflex pathway of Kearney, Stein & Parameswaran (1997): the joint velocity ``v = theta'`` (central
differences, taken before decimation by default: :class:`VelocitySettings`), delayed by ``d`` samples,
through a static nonlinearity ``N`` and a causal linear IRF ``h_R`` on the lags ``d ... d + L_R - 1``::

    T_R(t) = sum_k h_R(k) N(v(t - d - k))

``N`` is a half-wave rectifier of the stretch velocity (``rectifier``: ``max(sigma v, 0)``), the velocity
itself (``linear``) or a polynomial estimated with the IRF (``polynomial``: ``sum_j a_j T_j(v / v_max)``,
Chebyshev polynomials of the first kind, j = 1 ... order; a Hammerstein cascade). The lag window of the
reflex pathway (``reflex_window``) counts from lag 0, as the REKLAB toolbox's reflex IRF does: the IRF is
zero before the delay, so the delay must be shorter than the window.

A polynomial Hammerstein cascade is fitted by least squares on every product ``a_j h_R(k)`` (linear in
those), whose best rank-one approximation (SVD) starts alternating least squares on ``a`` given ``h_R``
and ``h_R`` given ``a``, which minimises the cascade's own output error (Hunter & Korenberg 1986 start
from correlations instead; the fixed point is the same least-squares cascade).

References
----------
Kearney, R. E., Stein, R. B. & Parameswaran, L. (1997). IEEE Trans. Biomed. Eng. 44(6), 493-504.
Westwick, D. T. & Kearney, R. E. (2003). Identification of Nonlinear Physiological Systems, Sec. 6.2
(Hammerstein cascades: the least-squares fit of the products and its rank-one reduction; iterative
methods).
"""
from __future__ import annotations

import dataclasses
import math
from typing import Literal

import numpy as np
from numpy.polynomial import chebyshev

from jointbench.core import differentiators
from jointbench.core.errors import InputError
from jointbench.core.intervals import psd_solve
from jointbench.core.schema import param
from jointbench.core.signal import Differentiate

Nonlinearity = Literal["rectifier", "polynomial", "linear"]

#: a delay bound within this many samples of a whole sample counts as that sample (:func:`delays`): the
#: rounding of ``seconds x fs`` (``0.07 s x 100 Hz = 7.000000000000001``), far below any delay a setting means
SAMPLE_ROUNDING = 1e-9
#: the normal equations are solved by :func:`jointbench.core.intervals.psd_solve`, which leaves out the directions
#: whose eigenvalue (of the unit-diagonal scaled matrix) is below
#: this fraction of the largest: eigenvalues are computed to about ``eps`` (2.2e-16) times the largest, so below
#: about 5000 ``eps`` a direction is rounding, not data (singular values of the scaled regressors below 1e-6 of
#: the largest)
RCOND = 1e-12
#: most alternations of :func:`hammerstein` (``h_R`` given ``a``, ``a`` given ``h_R``): a bound on the work, not
#: the stopping rule (the test suite's polynomial cascades stop by :data:`ALS_RTOL` after 5 ... 12)
ALS_ITERATIONS = 100
#: :func:`hammerstein` stops when one alternation lowers the residual by at most this fraction of it: about 5000
#: times its rounding (``eps``, 2.2e-16), and far below what a VAF shows
ALS_RTOL = 1e-12


@dataclasses.dataclass(frozen=True)
class VelocitySettings:
    """Where an estimator that differentiates the angle takes its velocity (mixed into its settings).

    'before_decimation' (the default) reads the velocity that :func:`jointbench.core.signal.resample_trial` took at
    the recorded rate before decimating the record (``decimate=`` of :func:`jointbench.api.fit`, ``jointbench
    estimate --decimate``), as the REKLAB toolbox's ``PC_stiffnessID`` differentiates before it decimates;
    'after_decimation' differentiates the angle as fitted. A record JointBench did not decimate has one velocity:
    both give the same numbers.

    The default is the more accurate of the two on a simulated ankle with a reflex (docs/reklab_parity.md, "Where
    to differentiate": K 140 N·m/rad, reflex gain 10 N·m·s/rad, recorded at 1 kHz, fitted by ``parallel_cascade``
    at 100 Hz, 5 seeds). With a perturbation whose velocity lies within the fitted band it is nearer the truth in
    intrinsic K, the reflex gain and the reflex torque (a multisine to 19 Hz: gain error 0.2 % against 9.6 %,
    K 0.4 % against 1.4 %; noise low-passed at 30 Hz: gain 8.8 % against 23 %, K 1.9 % against 4.8 %): central
    differences at 100 Hz are 10 % low at 10 Hz and 23 % low at 19 Hz, so after decimation the reflex pathway's
    input is too small and its gain too large. When the velocity reaches far beyond the fitted band (a PRBS
    through a stiff servo) both settings miss the reflex gain, in opposite directions (-20 % and +12 %): such a
    record is best fitted at a higher rate.

    References
    ----------
    Kearney, R. E., Stein, R. B. & Parameswaran, L. (1997). IEEE Trans. Biomed. Eng. 44(6), 493-504; the REKLAB
    toolbox's ``PC_stiffnessID`` (it differentiates the angle at the recorded rate, then decimates the velocity).
    """

    differentiate: Differentiate = param("before_decimation",
                                         doc="velocity of the angle from 'before_decimation' (at the recorded "
                                             "rate, as REKLAB) or 'after_decimation' (at the fitted rate)")



@dataclasses.dataclass(frozen=True)
class PathwaySettings:
    """The reflex pathway: its delay, lag window and static nonlinearity (mixed into an estimator's settings;
    where the velocity is taken is :class:`VelocitySettings`, mixed into those that read a decimated record's
    velocity channel)."""

    delay: float | None = param(None, unit="s", ge=0, doc="reflex delay; none: the one of delay_min ... delay_max "
                                                          "(every sample) of least minimum description length of "
                                                          "the joint fit of both pathways")
    delay_min: float = param(0.02, unit="s", ge=0, doc="shortest delay tried")
    delay_max: float = param(0.1, unit="s", ge=0, doc="longest delay tried")
    reflex_window: float = param(0.5, unit="s", gt=0, doc="lag window of the reflex IRF, from lag 0 (zero before "
                                                          "the delay)")
    nonlinearity: Nonlinearity = param("rectifier", doc="static nonlinearity: half-wave 'rectifier' of the "
                                                        "stretch velocity, 'polynomial' (estimated) or 'linear'")
    stretch: Literal["positive", "negative"] = param("positive", doc="velocity sign the rectifier passes")
    order: int = param(4, ge=1, le=12, doc="order of the polynomial nonlinearity")


@dataclasses.dataclass(frozen=True)
class ReflexSettings(PathwaySettings, VelocitySettings):
    """The reflex pathway and the parallel-cascade iteration (mixed into an estimator's settings)."""

    max_iter: int = param(20, ge=1, doc="most parallel-cascade iterations")
    tolerance: float = param(0.01, gt=0, doc="stop when the total VAF improves by less (percentage points)")
    keep_reflex: Literal["mdl", "always"] = param("mdl", doc="'mdl': keep the reflex pathway only when it lowers "
                                                             "the minimum description length; 'always'")


#: the velocity of an angle array sampled at ``fs`` (along axis 0): central differences (one home:
#: :func:`jointbench.core.differentiators.central`); a trial's, before or after decimation:
#: :func:`jointbench.core.signal.velocity`
velocity = differentiators.central


def delays(name: str, s: PathwaySettings, fs: float) -> tuple[np.ndarray, int]:
    """The candidate delays (samples) and the last lag ``W`` of the reflex lag window (samples): a delay
    ``d`` gives the reflex IRF the lags ``d ... W``.

    Raises
    ------
    InputError
        A delay not shorter than the reflex lag window (one line), or an empty range.
    """
    window = int(round(s.reflex_window * fs))
    if s.delay is not None:
        lo = hi = int(round(s.delay * fs))
        longest = s.delay
    else:
        if s.delay_min > s.delay_max:
            raise InputError(f"{name}: delay_min = {s.delay_min:g} s is above delay_max = {s.delay_max:g} s")
        lo, hi = int(math.ceil(s.delay_min * fs - SAMPLE_ROUNDING)), int(math.floor(s.delay_max * fs + SAMPLE_ROUNDING))
        longest = s.delay_max
        if hi < lo:
            raise InputError(f"{name}: no whole sample between delay_min = {s.delay_min:g} s and delay_max = "
                             f"{s.delay_max:g} s at {fs:g} Hz")
    if hi >= window:
        raise InputError(f"{name}: the reflex delay ({longest * 1e3:g} ms) is not shorter than the reflex lag window "
                         f"(reflex_window = {s.reflex_window * 1e3:g} ms, from lag 0): the reflex IRF would have no "
                         f"lags left; lengthen reflex_window or shorten the delay")
    return np.arange(lo, hi + 1), window


def basis(v: np.ndarray, s: PathwaySettings, scale: float) -> np.ndarray:
    """The nonlinearity's basis at the velocities ``v`` (any shape): a last axis of ``p`` functions."""
    v = np.asarray(v, float)
    sign = 1.0 if s.stretch == "positive" else -1.0
    if s.nonlinearity == "rectifier":
        return np.maximum(sign * v, 0.0)[..., None]
    if s.nonlinearity == "linear":
        return v[..., None]
    x = np.clip(v / scale, -1.0, 1.0)
    return chebyshev.chebvander(x, s.order)[..., 1:]            # T_1 ... T_order (T_0: the mean, removed)


@dataclasses.dataclass(frozen=True)
class StaticNonlinearity:
    """The fitted static nonlinearity ``N(v) = sum_j a_j phi_j(v)`` of the reflex pathway."""

    settings: ReflexSettings
    coef: np.ndarray        # a_j (one for the rectifier and the linear pathway)
    scale: float            # v_max of the polynomial's argument (rad/s)
    offset: float = 0.0     # the mean of N over the fitted record (removed from the pathway's input)

    def __call__(self, v: np.ndarray) -> np.ndarray:
        return basis(v, self.settings, self.scale) @ self.coef

    def describe(self) -> str:
        s = self.settings
        if s.nonlinearity == "rectifier":
            return f"half-wave rectifier of {'+' if s.stretch == 'positive' else '-'}velocity"
        if s.nonlinearity == "linear":
            return "none (linear in the velocity)"
        return f"polynomial of order {s.order} in v / {self.scale:.3g} rad/s (Chebyshev)"


def lag_matrix(x: np.ndarray, d: int, L: int) -> np.ndarray:
    """``X[i, k] = x[i - d - k]`` (zero before the record), ``k = 0 ... L - 1``, for ``x`` of shape (n,) or
    (n, p) (then (n, p, L))."""
    x = np.asarray(x, float)
    pad = np.zeros((d + L - 1,) + x.shape[1:])
    full = np.concatenate([pad, x])[:len(x) + L - 1]
    win = np.lib.stride_tricks.sliding_window_view(full, L, axis=0)     # (n, [p,] L): x[i - d - L + 1 ... i - d]
    return win[..., ::-1]


def hammerstein(G: np.ndarray, b: np.ndarray, p: int, L: int) -> tuple[np.ndarray, np.ndarray]:
    """The Hammerstein cascade ``(a, h_R)`` from the normal equations of its products: ``G`` (pL x pL) and
    ``b`` (pL) of the regressors ``phi_j(v(t - d - k))`` (column ``j L + k``) and the torque.

    The products ``c = a (x) h_R`` by least squares, their best rank-one approximation (SVD), then
    alternating least squares on ``h_R`` given ``a`` and ``a`` given ``h_R`` (each a small system formed
    from ``G``: no pass over the data) until the residual stops falling (:data:`ALS_RTOL`, at most
    :data:`ALS_ITERATIONS` alternations). ``p = 1``: ``a = 1``."""
    c = psd_solve(G, b, RCOND)[0]
    if p == 1:
        return np.ones(1), c
    U, S, Vt = np.linalg.svd(c.reshape(p, L))
    a, h = U[:, 0] * S[0], Vt[0]
    G4 = G.reshape(p, L, p, L)
    B = b.reshape(p, L)
    prev = np.inf
    for _ in range(ALS_ITERATIONS):
        h = psd_solve(np.einsum("j,jkil,i->kl", a, G4, a), a @ B, RCOND)[0]
        a = psd_solve(np.einsum("k,jkil,l->ji", h, G4, h), B @ h, RCOND)[0]
        c = np.outer(a, h).ravel()
        rss_part = float(c @ G @ c - 2 * c @ b)          # the residual up to the constant y'y
        if prev - rss_part <= ALS_RTOL * abs(rss_part):
            break
        prev = rss_part
    return a, h


def finish(a: np.ndarray, h: np.ndarray, s: ReflexSettings, scale: float,
           offset_cols: np.ndarray | None = None) -> tuple[StaticNonlinearity, np.ndarray]:
    """The fitted static nonlinearity (normalized: :func:`_normalized`) and the reflex IRF.

    ``offset_cols`` is the mean of each basis function over the fitted rows, removed from the pathway's
    input; None: none removed (the time-varying pathway, whose gain carries the mean,
    :mod:`estimators.parallel_cascade_tv`)."""
    offset_cols = np.zeros(len(a)) if offset_cols is None else offset_cols
    if len(a) > 1:
        a, h = _normalized(a, h, s, scale, offset_cols)
    return StaticNonlinearity(s, a, scale, float(offset_cols @ a)), h


def _normalized(a: np.ndarray, h: np.ndarray, s: ReflexSettings, scale: float,
                offset: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Resolve the cascade's scale: N spans as much over -v_max ... v_max as a half-wave rectifier does
    (v_max; so that h_R carries the pathway's gain, in N·m per rad/s, as with the rectifier), and h_R
    sums to >= 0."""
    grid = np.linspace(-scale, scale, 201)
    Ng = basis(grid, s, scale) @ a - offset @ a
    span = float(np.ptp(Ng))
    k = (scale / span) if span > 0 else 1.0
    a, h = a * k, h / k
    if np.sum(h) < 0:
        a, h = -a, -h
    return a, h


@dataclasses.dataclass(frozen=True)
class NormalEquations:
    """The normal equations of both pathways for every candidate delay at once.

    The regressors are the intrinsic IRF's lagged angle (``LI`` columns) and the reflex basis at the lags
    ``d_lo ... W`` (``p`` blocks of ``Lb = W - d_lo + 1`` columns), on the common rows (every lag inside
    the record); a candidate delay's reflex regressors are the lags ``d ... W`` of every block
    (:meth:`reflex_cols`), so one Gram matrix serves every candidate."""

    G: np.ndarray
    b: np.ndarray
    yy: float
    yy_centred: float
    N: int
    LI: int
    p: int
    W: int
    d_lo: int
    offset: np.ndarray          # the mean of each basis function over the rows (removed from the regressors)

    @classmethod
    def build(cls, u, v, y, rows: slice, m1: int, m2: int, cands: np.ndarray, W: int, s: ReflexSettings,
              scale: float) -> "NormalEquations":
        from jointbench.estimators._twosided import regressor

        U = regressor(u, m1, m2, "zero")[0][rows]
        Phi = basis(v, s, scale)
        offset = Phi[rows].mean(axis=0)
        Phi = Phi - offset
        d_lo = int(cands[0])
        X = lag_matrix(Phi, d_lo, W - d_lo + 1)[rows]       # (N, p, Lb)
        Z = np.concatenate([U, X.reshape(len(U), -1)], axis=1)
        yr = y[rows]
        return cls(G=Z.T @ Z, b=Z.T @ yr, yy=float(yr @ yr), yy_centred=float(np.sum((yr - yr.mean()) ** 2)),
                   N=len(yr), LI=U.shape[1], p=Phi.shape[1], W=W, d_lo=d_lo, offset=offset)

    def __add__(self, other: "NormalEquations") -> "NormalEquations":
        """The pooled normal equations of two records (same lags and candidates)."""
        return dataclasses.replace(self, G=self.G + other.G, b=self.b + other.b, yy=self.yy + other.yy,
                                   yy_centred=self.yy_centred + other.yy_centred, N=self.N + other.N)

    @property
    def intrinsic_cols(self) -> np.ndarray:
        return np.arange(self.LI)

    def length(self, d: int) -> int:
        """The reflex IRF's number of lags for delay ``d``: ``W - d + 1``."""
        return self.W - d + 1

    def reflex_cols(self, d: int) -> np.ndarray:
        """Columns of the reflex regressors ``phi_j(v(t - k))``, ``j`` major, ``k = d ... W``."""
        Lb = self.W - self.d_lo + 1
        j = np.arange(self.p)[:, None] * Lb
        return (self.LI + j + (d - self.d_lo) + np.arange(self.length(d))[None, :]).ravel()

    def best_delay(self, cands: np.ndarray) -> int:
        """The candidate of least minimum description length ``RSS (1 + k ln N / N)`` of the joint
        least-squares fit of both pathways with the reflex IRF on the lags ``d ... W``: the leading lags the
        data show to be zero. A shorter delay adds lags that explain nothing before the reflex begins, a
        longer one drops lags that do. With a second-order activation (which starts from zero) the first
        lag that matters, hence the delay found, is about one sample after the transport delay."""
        best, best_d = np.inf, int(cands[0])
        for d in cands:
            cols = np.r_[self.intrinsic_cols, self.reflex_cols(int(d))]
            G, b = self.G[np.ix_(cols, cols)], self.b[cols]
            c = psd_solve(G, b, RCOND)[0]
            score = mdl(max(self.yy - 2 * c @ b + c @ G @ c, 0.0), len(cols), self.N)
            if score < best:
                best, best_d = score, int(d)
        return best_d


def scan_settings(s: PathwaySettings) -> PathwaySettings:
    """The nonlinearity the delay is found with: the pathway's own, or for an estimated polynomial the
    half-wave rectifier of ``stretch`` (one regressor per lag: the polynomial's products would make the
    scan's model large and its residuals noisy; the delay needs the onset, not the shape)."""
    return dataclasses.replace(s, nonlinearity="rectifier") if s.nonlinearity == "polynomial" else s


def mdl(rss: float, n_params: int, n_rows: int) -> float:
    """Minimum description length ``RSS (1 + k ln N / N)`` (the criterion of the REKLAB toolbox's orders)."""
    return rss * (1.0 + n_params * math.log(n_rows) / n_rows)


def check_moving(name: str, v: np.ndarray) -> None:
    if not np.any(np.abs(v) > 0):
        raise InputError(f"{name}: the angle does not move (zero velocity); nothing drives a reflex pathway")
