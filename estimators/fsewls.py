"""FSEWLS: frequency separation and exponentially weighted least squares (Xu & Hollerbach 1998).

Time-varying ``I``, ``B``, ``K`` of ``tau = I theta'' + B theta' + K theta``: zero-phase high-pass
(eq. 3), state-variable filter (eq. 4), continuous-time EWLS integrated by RK4 (eqs. 5-6).
"""
from __future__ import annotations

import dataclasses
import functools
from typing import Literal

import numpy as np
import pandas as pd
import scipy.fft
from scipy import signal as sps

from estimators import Estimator, register
from jointbench.errors import InputError
from jointbench.estimate import ParametricEstimate
from jointbench.schema import param
from jointbench.types import Trial

_IU = np.triu_indices(3)  # the 6 unique entries of a symmetric 3 x 3 matrix


# ------------------------------------------------------------------------------------------ filters
def highpass(x: np.ndarray, fs: float, cutoff: float, order: int, ripple: float) -> np.ndarray:
    """Zero-phase Chebyshev type I high-pass ``H(s)`` of eq. 3, forward and backward, along the last axis.

    The filter is ``scipy.signal.cheby1(order, ripple, cutoff, 'highpass', fs=fs)`` (bilinear
    transform pre-warped at ``cutoff``, the pass-band edge where the gain is ``-ripple`` dB), run
    forward and backward in second-order sections: zero phase, magnitude ``|H|^2`` (``-2 ripple`` dB
    at ``cutoff``). Each end is extended over ``10 T_hp`` seconds (:func:`highpass_time_constant`) by
    the least-squares line through its last ``1/cutoff`` seconds: the slow (voluntary) part continues
    smoothly while the perturbation stops in angle and torque alike. Against odd reflection (the
    :func:`scipy.signal.sosfiltfilt` default) this cuts the error of the I, B, K estimates near the
    ends about ten-fold; Gustafsson's initial states do well only on signals without an offset.

    References
    ----------
    Xu & Hollerbach (1998), eq. 3 and Sec. III-B ("fourth-order Chebyshev filter ... 1 Hz").
    """
    sos = _highpass_sos(order, ripple, cutoff, fs).copy()
    n = x.shape[-1]
    w = max(2, min(n // 4, int(round(fs / cutoff))))
    pad = int(np.ceil(10.0 * highpass_time_constant(cutoff, order, ripple) * fs))
    u = np.arange(w) - (w - 1) / 2.0

    def line(seg, at):  # least-squares line through seg, evaluated at sample offsets `at` from its centre
        slope = (seg @ u) / (u @ u)
        return seg.mean(axis=-1)[..., None] + slope[..., None] * at

    ext = np.concatenate([line(x[..., :w], u[0] - np.arange(pad, 0, -1)), x,
                          line(x[..., -w:], u[-1] + np.arange(1, pad + 1))], axis=-1)
    return sps.sosfiltfilt(sos, ext, axis=-1, padtype=None)[..., pad:pad + n]


@functools.lru_cache(maxsize=32)
def _highpass_sos(order: int, ripple: float, cutoff: float, fs: float) -> np.ndarray:
    """Second-order sections of the high-pass of :func:`highpass`, designed once per setting (read-only)."""
    sos = sps.cheby1(order, ripple, cutoff, btype="highpass", fs=fs, output="sos")
    sos.flags.writeable = False
    return sos


@functools.lru_cache(maxsize=32)
def highpass_time_constant(cutoff: float, order: int, ripple: float) -> float:
    """Slowest time constant (s) of the analog Chebyshev high-pass (0.97 s at 1 Hz, order 4, 0.5 dB).

    References
    ----------
    Xu & Hollerbach (1998), eq. 3 and Appendix B (error of the high-pass filtering).
    """
    _, p, _ = sps.cheby1(order, ripple, 2 * np.pi * cutoff, btype="highpass", analog=True, output="zpk")
    return float(1.0 / np.min(np.abs(p.real)))


def svf_pole(cutoff: float, order: int, means: str) -> float:
    """Pole ``a`` (rad/s) of ``L(s) = s^(n-2) a^n / (s + a)^n`` for ``cutoff`` in Hz.

    ``means='a'``: ``a = 2 pi cutoff``. ``means='-3dB'``: the low-pass ``a^n / (s + a)^n`` is -3 dB at
    ``cutoff``, ``a = 2 pi cutoff / sqrt(2^(1/n) - 1)`` (39.4 rad/s for 3.2 Hz, n = 3).

    References
    ----------
    Xu & Hollerbach (1998), eq. 4 and Sec. III-B ("third-order ... cutoff frequency of 3.2 Hz").
    """
    w = 2.0 * np.pi * cutoff
    return w if means == "a" else w / np.sqrt(2.0 ** (1.0 / order) - 1.0)


def _odd_fast_len(n: int) -> int:
    """Smallest fast FFT length >= ``n`` that is odd (no Nyquist bin, so ``j w`` stays exact)."""
    m = scipy.fft.next_fast_len(n, real=True)
    return m if m % 2 else _odd_fast_len(m + 1)


def svf(theta: np.ndarray, tau: np.ndarray, fs: float, a: float, order: int,
        causal: bool, form: str = "printed") -> tuple[np.ndarray, np.ndarray]:
    """Regressors ``Phi = [s^2 L theta, s L theta, L theta]`` and output ``y = L tau`` (eq. 4).

    The filters act in the frequency domain with their exact continuous responses at ``s = j w`` (the
    samples read as band-limited) on records zero-padded by ``40/a`` seconds at each end, with an odd
    FFT length, so nothing wraps around. ``causal=True``: ``L(jw) = (jw)^(n-2) a^n / (jw + a)^n``
    itself, starting from rest at the first sample; it delays the signals by about ``n/a`` at low
    frequencies. ``causal=False`` (zero phase): the differentiator ``(jw)^(n-2)`` is kept and the
    low-pass replaced by its magnitude ``(a^2 / (a^2 + w^2))^(n/2)``, so ``|L|`` is unchanged and no
    lag is added; acausal, it settles within about ``10/a`` seconds of each end. ``form='lowpass'``
    drops the factor ``s^(n-2)``: ``L = a^n / (s + a)^n``, the "third-order low-pass filter" of the
    paper's Sec. III-B (the printed eq. 4 form has a zero at s = 0 and a flat acceleration regressor).

    ``theta``, ``tau`` (high-passed) have shape (..., n); ``Phi`` (..., n, 3) and ``y`` (..., n).

    References
    ----------
    Xu & Hollerbach (1998), eq. 4 and Appendix A.
    """
    n = theta.shape[-1]
    pad = int(np.ceil(40.0 / a * fs))
    nfft = _odd_fast_len(n + 2 * pad)
    f = scipy.fft.rfftfreq(nfft, 1.0 / fs)
    jw = 2j * np.pi * f
    if causal:
        low = (a / (jw + a)) ** order
    else:
        low = (a * a / (a * a + (2 * np.pi * f) ** 2)) ** (order / 2.0)
    widths = [(0, 0)] * (theta.ndim - 1) + [(pad, nfft - n - pad)]
    spec = scipy.fft.rfft(np.stack([np.pad(theta, widths), np.pad(tau, widths)]), axis=-1)
    base = low * jw ** (order - 2) if form == "printed" else low
    ops = np.stack([spec[0] * (base * jw * jw), spec[0] * (base * jw), spec[0] * base, spec[1] * base])
    out = scipy.fft.irfft(ops, nfft, axis=-1)[..., pad:pad + n]
    return np.moveaxis(out[:3], 0, -1), out[3]


# ---------------------------------------------------------------------------------------- EWLS (eq. 6)
def rk4_coefficients(lam: float, h: float) -> tuple[float, float, float, float]:
    """One classical RK4 step of ``x' = -lam x + f(t)`` written as ``c x0 + w0 f0 + wm fm + w1 f1``.

    ``f0``, ``fm``, ``f1``: forcing at the start, middle and end of the step. With ``z = lam h``,
    ``c = 1 - z + z^2/2 - z^3/6 + z^4/24``, ``w0 = h/6 (1 - z + z^2/2 - z^3/4)``,
    ``wm = h/6 (4 - 2 z + z^2/2)``, ``w1 = h/6`` (expanding the stages ``k1 ... k4``; ``z = 0`` gives
    Simpson's rule).

    References
    ----------
    Xu & Hollerbach (1998), Sec. II-D ("fourth-order Runge-Kutta ... step size equal to the sampling period").
    """
    z = lam * h
    c = 1.0 - z + z * z / 2.0 - z ** 3 / 6.0 + z ** 4 / 24.0
    return c, h / 6 * (1.0 - z + z * z / 2.0 - z ** 3 / 4.0), h / 6 * (4.0 - 2.0 * z + z * z / 2.0), h / 6


def _products(Phi: np.ndarray, y: np.ndarray) -> np.ndarray:
    """``[unique entries of Phi Phi^T, Phi y]`` per sample, summed over records, shape (9, n).

    ``Phi`` has shape (3, n_records, n) (regressor first: each product is one contiguous pass), ``y``
    (n_records, n).
    """
    out = np.empty((9, y.shape[-1]))
    for m, (i, j) in enumerate(zip(*_IU)):
        np.einsum("rn,rn->n", Phi[i], Phi[j], out=out[m])
    for i in range(3):
        np.einsum("rn,rn->n", Phi[i], y, out=out[6 + i])
    return out


def _forcing(Phi: np.ndarray, y: np.ndarray) -> np.ndarray:
    """``[unique entries of Phi Phi^T, Phi y]`` per sample, summed over records: shape (n, 9).

    ``Phi`` has shape (n_records, n, 3), ``y`` (n_records, n).
    """
    return _products(np.moveaxis(Phi, -1, 0), y).T


def _unpack(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    R = np.empty(x.shape[:-1] + (3, 3))
    R[..., _IU[0], _IU[1]] = R[..., _IU[1], _IU[0]] = x[..., :6]
    return R, x[..., 6:]


def _solve_spd3(x: np.ndarray) -> np.ndarray:
    """``R^-1 r`` per sample from ``x`` = [unique entries of R, r], shape (9, n); ``R`` symmetric positive
    definite. Returns shape (n, 3).

    Columns scaled so that the mean diagonal of ``R`` is 1, then ``R = L D L^T`` written out for 3 x 3
    (no pivoting is needed for a positive definite matrix) and two triangular solves, every step one
    vectorised operation over the samples.
    """
    s = 1.0 / np.sqrt(x[[0, 3, 5]].mean(axis=1))
    a00, a01, a02, a11, a12, a22 = (x[k] * (s[i] * s[j]) for k, (i, j) in enumerate(zip(*_IU)))
    b0, b1, b2 = x[6] * s[0], x[7] * s[1], x[8] * s[2]
    l10, l20 = a01 / a00, a02 / a00
    d1 = a11 - l10 * a01
    e12 = a12 - l20 * a01
    l21 = e12 / d1
    d2 = a22 - l20 * a02 - l21 * e12
    if not (np.all(d1 > 0) and np.all(d2 > 0) and np.all(a00 > 0)):
        raise np.linalg.LinAlgError("EWLS information matrix is not positive definite")
    z1 = b1 - l10 * b0
    x2 = (b2 - l20 * b0 - l21 * z1) / d2
    x1 = (z1 - e12 * x2) / d1
    x0 = (b0 - a01 * x1 - a02 * x2) / a00
    return np.stack([x0 * s[0], x1 * s[1], x2 * s[2]], axis=1)


def ewls(Phi: np.ndarray, y: np.ndarray, dt: float, lam: float, R0: np.ndarray,
         r0: np.ndarray) -> np.ndarray:
    """Continuous-time EWLS (eq. 6) by classical RK4 at step ``dt``, in information form (fast).

    With ``R = P^-1`` and ``r = R Theta`` eq. 6 is linear: ``R' = -lam R + Phi Phi^T``,
    ``r' = -lam r + Phi y``, ``Theta = R^-1 r`` (records pool by summing ``Phi Phi^T`` and ``Phi y``).
    RK4 with ``Phi`` and ``y`` linearly interpolated at the mid-points is then exactly the recursion of
    :func:`rk4_coefficients` on the products at the samples and at the mid-points, run by
    :func:`scipy.signal.lfilter`, followed by a column-scaled 3 x 3 solve per sample (:func:`_solve_spd3`).
    RK4 is not invariant under the change of variables ``(P, Theta) -> (R, r)``: the result differs
    from RK4 on eq. 6 itself (:func:`_ewls_riccati_rk4`) by RK4's truncation error, ``O(dt^4)``; the tests
    check they agree. The nine products are laid out one per row (9, n), so every step of the
    arithmetic (about 200 flops per sample) is one contiguous vectorised pass.

    ``Phi`` has shape (n_records, n, 3), ``y`` (n_records, n); ``dt`` is the step (s), ``lam`` the
    forgetting rate (1/s), ``R0 = P(0)^-1`` and ``r0 = P(0)^-1 Theta(0)``. Returns ``[I, B, K]`` per
    sample, shape (n, 3).

    References
    ----------
    Xu & Hollerbach (1998), eqs. 5-6 and Sec. II-D.
    """
    c, w0, wm, w1 = rk4_coefficients(lam, dt)
    P = np.ascontiguousarray(np.moveaxis(Phi, -1, 0))           # (3, n_records, n)
    y = np.ascontiguousarray(y)
    f = _products(P, y)
    fm = _products(0.5 * (P[..., 1:] + P[..., :-1]), 0.5 * (y[:, 1:] + y[:, :-1]))
    drive = np.empty_like(f)
    drive[:, 0] = np.concatenate([R0[_IU], r0])
    d = drive[:, 1:]
    np.multiply(f[:, :-1], w0, out=d)
    d += wm * fm
    d += w1 * f[:, 1:]
    return _solve_spd3(sps.lfilter([1.0], [1.0, -c], drive, axis=-1))


def ewls_start(Phi: np.ndarray, y: np.ndarray, fs: float, init_window: float) -> tuple[np.ndarray, np.ndarray]:
    """``R0 = P(0)^-1`` and ``r0 = R0 Theta(0)`` of eq. 6 by least squares over the first ``init_window``
    seconds: ``R0 = sum of Phi Phi^T dt`` and ``r0 = sum of Phi y dt`` over that window (``dt = 1/fs``),
    so that ``Theta(0) = R0^-1 r0`` is the ordinary least-squares fit there.

    References
    ----------
    Xu & Hollerbach (1998), Sec. II-D ("initial values ... calculated using standard least squares").
    """
    m = max(int(round(init_window * fs)), 3)
    return _unpack(_forcing(Phi[:, :m], y[:, :m]).sum(axis=0) / fs)


def ewls_regression(Phi: np.ndarray, y: np.ndarray, fs: float, forgetting: float, init_window: float) -> np.ndarray:
    """EWLS (eq. 6) on given regressors ``Phi`` (n_records, n, 3) and output ``y`` (n_records, n), started as
    :class:`FSEWLS` starts it (:func:`ewls_start`): the estimator's last two steps without its filters. For
    controls that feed exact signals (e.g. the true derivatives of a simulation). Returns ``[I, B, K]`` per
    sample, shape (n, 3).

    References
    ----------
    Xu & Hollerbach (1998), eqs. 5-6 and Sec. II-D.
    """
    R0, r0 = ewls_start(Phi, y, fs, init_window)
    return ewls(Phi, y, 1.0 / fs, forgetting, R0, r0)


def _ewls_riccati_rk4(Phi: np.ndarray, y: np.ndarray, dt: float, lam: float, P0: np.ndarray,
                      theta0: np.ndarray) -> np.ndarray:
    """Reference for the tests: plain classical RK4 on eq. 6 in ``(P, Theta)`` for one record (slow).

    ``Theta' = P Phi (y - Phi^T Theta)``, ``P' = -P Phi Phi^T P + lam P``, step ``dt``, ``Phi`` (n, 3)
    and ``y`` (n,) linearly interpolated at the mid-points. Returns ``Theta``, shape (n, 3).

    References
    ----------
    Xu & Hollerbach (1998), eq. 6 and Sec. II-D.
    """
    def rate(P, th, phi, yk):
        g = P @ phi
        return lam * P - np.outer(g, phi @ P), g * (yk - phi @ th)

    out = np.empty((len(y), 3))
    P, th = np.array(P0, float), np.array(theta0, float)
    out[0] = th
    for k in range(len(y) - 1):
        pm, ym = 0.5 * (Phi[k] + Phi[k + 1]), 0.5 * (y[k] + y[k + 1])
        dP1, dt1 = rate(P, th, Phi[k], y[k])
        dP2, dt2 = rate(P + 0.5 * dt * dP1, th + 0.5 * dt * dt1, pm, ym)
        dP3, dt3 = rate(P + 0.5 * dt * dP2, th + 0.5 * dt * dt2, pm, ym)
        dP4, dt4 = rate(P + dt * dP3, th + dt * dt3, Phi[k + 1], y[k + 1])
        P = P + dt / 6.0 * (dP1 + 2.0 * dP2 + 2.0 * dP3 + dP4)
        th = th + dt / 6.0 * (dt1 + 2.0 * dt2 + 2.0 * dt3 + dt4)
        out[k + 1] = th
    return out


# ------------------------------------------------------------------------------------------ estimate
@dataclasses.dataclass(eq=False, kw_only=True)
class FSEWLSEstimate(ParametricEstimate):
    """Time-varying ``I``, ``B``, ``K`` (arrays on :attr:`time`, the first record's) from FSEWLS.

    Attributes
    ----------
    filtered_torque : ndarray, shape (n_records, n)
        ``y = L H tau``, the output of the regression (eqs. 3-5).
    predicted_filtered_torque : ndarray, shape (n_records, n)
        ``Phi^T Theta`` with the parameters at each sample.
    transient : float
        Seconds at each end affected by the filters and the EWLS start (:meth:`FSEWLS.transient`).
    highpassed : ndarray, shape (2, n_records, n)
        Angle and torque after the high-pass ``H`` (eq. 3; as measured when it is off), means kept.

    :attr:`valid` = :meth:`steady` (read by :func:`jointbench.ensemble.valid_mask`). :meth:`predict` and :meth:`frequency_response` give torque from angle (impedance), whichever
    signal the trial imposed.

    References
    ----------
    Xu & Hollerbach (1998), eqs. 2-6.
    """

    filtered_torque: np.ndarray
    predicted_filtered_torque: np.ndarray
    transient: float
    highpassed: np.ndarray | None = None

    def steady(self) -> np.ndarray:
        """Boolean mask of the samples at least :attr:`transient` seconds from both ends."""
        t = self.time
        return (t - t[0] >= self.transient) & (t[-1] - t >= self.transient)

    valid = property(steady)

    def damping_ratio(self) -> np.ndarray:
        """``B / (2 sqrt(K I))`` on :attr:`time`; NaN where ``K I <= 0`` (possible in transients).

        References
        ----------
        Xu & Hollerbach (1998), Sec. V-B (damping ratio, Figs. 8-9).
        """
        ki = self.K * self.I
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.where(ki > 0, self.B / (2.0 * np.sqrt(np.abs(ki))), np.nan)

    def output_vaf(self, steady_only: bool = True) -> float:
        """VAF (%) of the predicted filtered torque, ``100 (1 - var(y - yhat) / var(y))``, pooled over the
        records, on the :meth:`steady` samples unless ``steady_only=False``.

        References
        ----------
        Xu & Hollerbach (1998), Sec. III-B and Fig. 2 ("VAF of the output prediction").
        """
        keep = self.steady() if steady_only else np.ones(len(self.time), bool)
        y = self.filtered_torque[:, keep]
        if y.size < 2 or np.var(y) == 0:
            raise ValueError("output_vaf: no samples with a varying filtered torque")
        return float(100.0 * (1.0 - np.var(y - self.predicted_filtered_torque[:, keep]) / np.var(y)))

    def frequency_response(self, f: np.ndarray, t=None) -> np.ndarray:
        """Frozen impedance ``K(t) + j w B(t) - I(t) w^2`` at times ``t`` (s), frequencies ``f`` (Hz)."""
        if t is None:
            raise ValueError("fsewls: the estimate varies in time; give the time(s) t")
        w = 2 * np.pi * np.asarray(f, float)
        ts = np.asarray(t, float)
        p = {k: self._on(getattr(self, k), np.atleast_1d(ts))[:, None] for k in ("I", "B", "K")}
        H = p["K"] + 1j * w * p["B"] - p["I"] * w ** 2
        return H[0] if ts.ndim == 0 else H

    def to_frame(self) -> pd.DataFrame:
        """``time``, ``I``, ``B``, ``K``, ``stiffness``, ``steady``, then per record ``filtered_torque``
        and ``predicted_filtered_torque`` (suffixed ``_1``, ``_2`` ... from the second record on)."""
        frame = super().to_frame()
        frame["steady"] = self.steady()
        for k, (y, yhat) in enumerate(zip(self.filtered_torque, self.predicted_filtered_torque)):
            frame[f"filtered_torque{f'_{k}' if k else ''}"] = y
            frame[f"predicted_filtered_torque{f'_{k}' if k else ''}"] = yhat
        return frame

    def summary(self):
        out = {**super().summary(), "transient_s": float(self.transient)}
        return {**out, "output_vaf": self.output_vaf()} if self.steady().sum() > 1 else out


# ----------------------------------------------------------------------------------------- estimator
@register("fsewls", tags=("ltv", "parametric", "recursive"))
class FSEWLS(Estimator):
    """Time-varying I, B, K by frequency separation and exponentially weighted least squares.

    1. ``H``: zero-phase Chebyshev type I high-pass of angle and torque (:func:`highpass`, eq. 3).
    2. ``L(s) = s^(n-2) a^n / (s + a)^n``: ``Phi = [s^2 L, s L, L] theta~``, ``y = L tau~``
       (:func:`svf`, eq. 4); zero phase unless ``svf_causal``.
    3. EWLS ``Theta' = P Phi (y - Phi^T Theta)``, ``P' = -P Phi Phi^T P + lam P`` (eq. 6) by classical
       RK4 at the sampling period, mid-points by linear interpolation (:func:`ewls`). ``Theta(0)`` is
       the ordinary least-squares fit to the first ``init_window`` seconds and
       ``P(0) = (sum of Phi Phi^T dt over that window)^-1``, the inverse of the information the window
       holds on the time scale of eq. 6.

    The impedance (torque from angle) is fitted whichever signal the trial imposed; means are removed
    before L. Aligned records of equal length are pooled instant by instant (their ``Phi Phi^T`` and
    ``Phi y`` add in eq. 6). Each end loses ``transient = 3 T_hp + 10/a + 7/forgetting`` seconds
    (:meth:`transient`; ``T_hp`` is the slowest time constant of the high-pass, 0.97 s at 1 Hz), and a
    record shorter than ``2 transient + init_window`` is refused.

    Parameters
    ----------
    settings : Settings
        ``highpass_cutoff`` (Hz, 1; none = off), ``highpass_order`` (4), ``highpass_ripple`` (dB, 0.5,
        not in the paper), ``svf_order`` (3), ``svf_cutoff`` (Hz, 3.2), ``svf_cutoff_means`` ('-3dB'),
        ``svf_causal`` (false), ``forgetting`` (1/s, 20), ``init_window`` (s, 0.5).

    Notes
    -----
    Readings (study sheet A): H is "zero-phase-shift acausal"; for L the paper does not say. A causal L
    lags the estimates by about ``n/a`` (76 ms at a = 39.4 rad/s, 149 ms at 2 pi 3.2 rad/s) on top of
    the EWLS lag ``1/lam``, too much for the paper's Fig. 2: the default is zero phase with ``|L|``
    kept. "Cutoff frequency" is read as the -3 dB point of ``a^n / (s + a)^n``.

    References
    ----------
    Xu, Y. & Hollerbach, J. M. (1998). Identification of human joint mechanical properties from single
    trial data. IEEE Trans. Biomed. Eng., eqs. 3-6 and Sec. III-B.
    """

    @dataclasses.dataclass(frozen=True)
    class Settings:
        highpass_cutoff: float | None = param(1.0, unit="Hz", gt=0, doc="edge of the high-pass H (eq. 3); none = off")
        highpass_order: int = param(4, ge=1, doc="order of the Chebyshev type I high-pass (run both ways)")
        highpass_ripple: float = param(0.5, unit="dB", gt=0, doc="pass-band ripple of the high-pass")
        svf_order: int = param(3, ge=2, doc="order n of L(s) = s^(n-2) a^n / (s + a)^n (eq. 4)")
        svf_cutoff: float = param(3.2, unit="Hz", gt=0, doc="cutoff of the state-variable filter L")
        svf_cutoff_means: Literal["-3dB", "a"] = param("-3dB", doc="-3 dB point of a^n/(s+a)^n, or 'a' (2 pi cutoff)")
        svf_causal: bool = param(False, doc="true: causal L (lags ~ n/a); false: zero phase, |L| kept")
        svf_form: Literal["printed", "lowpass"] = param("printed", doc="L = s^(n-2) a^n/(s+a)^n as printed, or a^n/(s+a)^n")
        forgetting: float = param(20.0, unit="1/s", gt=0, doc="forgetting rate lambda of the EWLS (eq. 6)")
        init_window: float = param(0.5, unit="s", gt=0, doc="first seconds fitted for Theta(0) and P(0)")

    def pole(self) -> float:
        """Pole ``a`` (rad/s) of the state-variable filter."""
        s = self.settings
        return svf_pole(s.svf_cutoff, s.svf_order, s.svf_cutoff_means)

    def transient(self) -> float:
        """Seconds discarded at each end: ``3 T_hp + 10/a + 7/forgetting`` (``T_hp = 0`` without H)."""
        s = self.settings
        hp = 0.0 if s.highpass_cutoff is None else 3.0 * highpass_time_constant(
            s.highpass_cutoff, s.highpass_order, s.highpass_ripple)
        return hp + 10.0 / self.pole() + 7.0 / s.forgetting

    def _check(self, trials: list[Trial]) -> None:
        s, first = self.settings, trials[0]
        fs, where = first.fs, f"{self.name}: trial '{first.name}'"
        if any(t.n != first.n for t in trials):
            raise InputError(f"{self.name}: pooled records must be aligned and of equal length, got "
                             f"{sorted({t.n for t in trials})} samples")
        for t in trials:  # Trial rejects non-finite data; guard against arrays changed afterwards
            if not (np.isfinite(t.angle).all() and np.isfinite(t.torque).all()):
                raise InputError(f"{self.name}: trial '{t.name}' has non-finite angle or torque (NaN or inf)")
        if s.highpass_cutoff is not None and not s.highpass_cutoff < fs / 2:
            raise InputError(f"{where}: highpass_cutoff = {s.highpass_cutoff:g} Hz must be below the "
                             f"Nyquist frequency {fs / 2:g} Hz")
        a = self.pole()
        if a > 2 * np.pi * fs / 10:
            raise InputError(f"{where}: the state-variable filter's pole a = {a:.4g} rad/s ({a / (2 * np.pi):.4g}"
                             f" Hz, from svf_cutoff = {s.svf_cutoff:g} Hz, svf_cutoff_means = "
                             f"{s.svf_cutoff_means!r}) must be at most fs/10 = {fs / 10:g} Hz")
        if s.forgetting / fs > 0.5:
            raise InputError(f"{where}: forgetting = {s.forgetting:g} 1/s is too fast for {fs:g} Hz: the RK4 "
                             f"step needs forgetting / fs <= 0.5")
        need = 2 * self.transient() + s.init_window
        if first.duration < need:
            raise InputError(f"{where}: {first.n} samples ({first.duration:.3g} s) are too short: FSEWLS "
                             f"needs 2 x {self.transient():.3g} s of transients (from highpass_cutoff, "
                             f"svf_cutoff and forgetting) + init_window {s.init_window:g} s = {need:.3g} s")

    def _fit(self, trials: list[Trial]) -> FSEWLSEstimate:
        self._check(trials)
        s, fs = self.settings, trials[0].fs
        x = np.stack([[t.angle for t in trials], [t.torque for t in trials]])
        size = np.abs(x[0]).max(axis=-1)
        if s.highpass_cutoff is not None:
            x = highpass(x, fs, s.highpass_cutoff, s.highpass_order, s.highpass_ripple)
        highpassed, (theta, tau) = x, x - x.mean(axis=-1, keepdims=True)
        Phi, y = svf(theta, tau, fs, self.pole(), s.svf_order, s.svf_causal, s.svf_form)
        R0, r0 = ewls_start(Phi, y, fs, s.init_window)
        scale = np.sqrt(np.diag(R0))
        if (np.any(np.std(theta, axis=-1) <= 1e-10 * size) or not np.all(scale > 0)
                or np.linalg.cond(R0 / np.multiply.outer(scale, scale)) > 1e12):
            raise InputError(f"{self.name}: trial '{trials[0].name}': the filtered angle cannot separate I, "
                             f"B and K in the first init_window = {s.init_window:g} s (constant angle or "
                             f"no perturbation?)")
        try:
            Theta = ewls(Phi, y, 1.0 / fs, s.forgetting, R0, r0)
        except np.linalg.LinAlgError:
            raise InputError(f"{self.name}: trial '{trials[0].name}': the EWLS information matrix became "
                             f"singular (no perturbation for much longer than 1/forgetting?)") from None
        return FSEWLSEstimate(I=Theta[:, 0], B=Theta[:, 1], K=Theta[:, 2], fs=fs, time=trials[0].time,
                              estimator=self.name, filtered_torque=y,
                              predicted_filtered_torque=np.einsum("rni,ni->rn", Phi, Theta),
                              transient=self.transient(), highpassed=highpassed)
