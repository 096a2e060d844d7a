"""The numerical kernels of FSEWLS (Xu & Hollerbach 1998): the zero-phase high-pass (eq. 3), the
state-variable filter (eq. 4) and the continuous-time EWLS integrated by RK4 (eqs. 5-6).

:mod:`estimators.fsewls` wraps them in the estimator.

References
----------
Xu, Y. & Hollerbach, J. M. (1998). Identification of human joint mechanical properties from single
trial data. IEEE Trans. Biomed. Eng., eqs. 3-6.
"""
from __future__ import annotations

import functools

import numpy as np
import scipy.fft
from scipy import signal as sps


UPPER3 = np.triu_indices(3)  # the 6 unique entries of a symmetric 3 x 3 matrix


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
    sos, zi = highpass_sos(order, ripple, cutoff, fs), _highpass_zi(order, ripple, cutoff, fs)
    sos = sos.copy()                                   # sosfilt wants a writable array
    n = x.shape[-1]
    w = max(2, min(n // 4, int(round(fs / cutoff))))
    pad = int(np.ceil(10.0 * highpass_time_constant(cutoff, order, ripple) * fs))
    u = np.arange(w) - (w - 1) / 2.0

    def line(seg, at):  # least-squares line through seg, evaluated at sample offsets `at` from its centre
        slope = (seg @ u) / (u @ u)
        return seg.mean(axis=-1)[..., None] + slope[..., None] * at

    ext = np.concatenate([line(x[..., :w], u[0] - np.arange(pad, 0, -1)), x,
                          line(x[..., -w:], u[-1] + np.arange(1, pad + 1))], axis=-1)
    # scipy.signal.sosfiltfilt(sos, ext, axis=-1, padtype=None) step by step, its initial states designed once
    zi = zi.reshape((len(sos),) + (1,) * (ext.ndim - 1) + (2,))
    fwd, _ = sps.sosfilt(sos, ext, axis=-1, zi=zi * ext[..., :1])
    bwd, _ = sps.sosfilt(sos, fwd[..., ::-1], axis=-1, zi=zi * fwd[..., -1:])
    return bwd[..., ::-1][..., pad:pad + n]


@functools.lru_cache(maxsize=32)
def highpass_sos(order: int, ripple: float, cutoff: float, fs: float) -> np.ndarray:
    """Second-order sections of the high-pass of :func:`highpass`, designed once per setting (read-only)."""
    sos = sps.cheby1(order, ripple, cutoff, btype="highpass", fs=fs, output="sos")
    sos.flags.writeable = False
    return sos


@functools.lru_cache(maxsize=32)
def _highpass_zi(order: int, ripple: float, cutoff: float, fs: float) -> np.ndarray:
    """Step-response initial states of :func:`highpass_sos` (:func:`scipy.signal.sosfilt_zi`), shape
    (n_sections, 2), once per setting (read-only)."""
    zi = sps.sosfilt_zi(highpass_sos(order, ripple, cutoff, fs).copy())
    zi.flags.writeable = False
    return zi


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


def odd_fast_len(n: int) -> int:
    """Smallest fast FFT length >= ``n`` that is odd (no Nyquist bin, so ``j w`` stays exact)."""
    m = scipy.fft.next_fast_len(n, real=True)
    return m if m % 2 else odd_fast_len(m + 1)


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
    nfft = odd_fast_len(n + 2 * pad)
    mult = _svf_multipliers(nfft, fs, a, order, causal, form)
    buf = np.zeros((2,) + theta.shape[:-1] + (nfft,))                # both records, zero-padded
    buf[0, ..., pad:pad + n] = theta
    buf[1, ..., pad:pad + n] = tau
    spec = scipy.fft.rfft(buf, axis=-1)
    # the products as first written, ``spec * (base * jw * jw)``, ``spec * (base * jw)``, ``spec * base``: on a
    # large temporary numpy multiplies in place into it, a loop whose rounding can differ (complex, 1-D), so
    # the first two act on fresh copies of their multipliers and the last two on the shared one
    ops = np.stack([spec[0] * mult[0].copy(), spec[0] * mult[1].copy(), spec[0] * mult[2], spec[1] * mult[2]])
    out = scipy.fft.irfft(ops, nfft, axis=-1)[..., pad:pad + n]
    return np.moveaxis(out[:3], 0, -1), out[3]


@functools.lru_cache(maxsize=8)
def _svf_multipliers(nfft: int, fs: float, a: float, order: int, causal: bool, form: str) -> np.ndarray:
    """``[s^2 L, s L, L]`` of :func:`svf` at ``s = j w`` on the ``rfft`` bins of ``nfft`` samples, shape
    (3, nfft // 2 + 1), computed once per setting and record length (read-only)."""
    f = scipy.fft.rfftfreq(nfft, 1.0 / fs)
    jw = 2j * np.pi * f
    if causal:
        low = (a / (jw + a)) ** order
    else:
        low = (a * a / (a * a + (2 * np.pi * f) ** 2)) ** (order / 2.0)
    base = low * jw ** (order - 2) if form == "printed" else low
    mult = np.stack([base * jw * jw, base * jw, base])
    mult.flags.writeable = False
    return mult


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


def products(Phi: np.ndarray, y: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
    """``[unique entries of Phi Phi^T, Phi y]`` per sample, summed over records, shape (9, n).

    ``Phi`` has shape (3, n_records, n) (regressor first: each product is one contiguous pass), ``y``
    (n_records, n); ``out``, if given, a (9, n) array written in place.
    """
    if out is None:
        out = np.empty((9, y.shape[-1]))
    for m, (i, j) in enumerate(zip(*UPPER3)):
        np.einsum("rn,rn->n", Phi[i], Phi[j], out=out[m])
    for i in range(3):
        np.einsum("rn,rn->n", Phi[i], y, out=out[6 + i])
    return out


def forcing(Phi: np.ndarray, y: np.ndarray) -> np.ndarray:
    """``[unique entries of Phi Phi^T, Phi y]`` per sample, summed over records: shape (n, 9).

    ``Phi`` has shape (n_records, n, 3), ``y`` (n_records, n).
    """
    return products(np.moveaxis(Phi, -1, 0), y).T


def unpack(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    R = np.empty(x.shape[:-1] + (3, 3))
    R[..., UPPER3[0], UPPER3[1]] = R[..., UPPER3[1], UPPER3[0]] = x[..., :6]
    return R, x[..., 6:]


def solve_spd3(x: np.ndarray) -> np.ndarray:
    """``R^-1 r`` per sample from ``x`` = [unique entries of R, r], shape (9, n); ``R`` symmetric positive
    definite. Returns shape (n, 3).

    Columns scaled so that the mean diagonal of ``R`` is 1, then ``R = L D L^T`` written out for 3 x 3
    (no pivoting is needed for a positive definite matrix) and two triangular solves, per sample in one
    compiled loop (:func:`jointbench.estimators._ewls_loops.solve3`; tests/test_fsewls.py keeps the numpy
    formulation it replaced, the same numbers to the last bit).

    Raises
    ------
    numpy.linalg.LinAlgError
        ``R`` is not positive definite at some sample.
    """
    from jointbench.estimators import _ewls_loops

    x = np.ascontiguousarray(x, dtype=float)
    s = 1.0 / np.sqrt(x[[0, 3, 5]].mean(axis=1))
    out = np.empty((x.shape[-1], 3))
    if not _ewls_loops.solve3(x, s, out):
        raise np.linalg.LinAlgError("EWLS information matrix is not positive definite")
    return out


def ewls(Phi: np.ndarray, y: np.ndarray, dt: float, lam: float, R0: np.ndarray,
         r0: np.ndarray) -> np.ndarray:
    """Continuous-time EWLS (eq. 6) by classical RK4 at step ``dt``, in information form (fast).

    With ``R = P^-1`` and ``r = R Theta`` eq. 6 is linear: ``R' = -lam R + Phi Phi^T``,
    ``r' = -lam r + Phi y``, ``Theta = R^-1 r`` (records pool by summing ``Phi Phi^T`` and ``Phi y``).
    RK4 with ``Phi`` and ``y`` linearly interpolated at the mid-points is then exactly the recursion of
    :func:`rk4_coefficients` on the products at the samples and at the mid-points (compiled:
    :func:`jointbench.estimators._ewls_loops.recursion`, the numbers of ``scipy.signal.lfilter`` on the
    drive; it pays for itself, issue 34), followed by a column-scaled 3 x 3 solve per sample
    (:func:`solve_spd3`).
    RK4 is not invariant under the change of variables ``(P, Theta) -> (R, r)``: the result differs
    from RK4 on eq. 6 itself (:func:`ewls_riccati_rk4`) by RK4's truncation error, ``O(dt^4)``; the tests
    check they agree.

    ``Phi`` has shape (n_records, n, 3), ``y`` (n_records, n); ``dt`` is the step (s), ``lam`` the
    forgetting rate (1/s), ``R0 = P(0)^-1`` and ``r0 = P(0)^-1 Theta(0)``. Returns ``[I, B, K]`` per
    sample, shape (n, 3).

    References
    ----------
    Xu & Hollerbach (1998), eqs. 5-6 and Sec. II-D.
    """
    from jointbench.estimators import _ewls_loops

    c, w0, wm, w1 = rk4_coefficients(lam, dt)
    P = np.ascontiguousarray(np.moveaxis(Phi, -1, 0), dtype=float)    # (3, n_records, n)
    y = np.ascontiguousarray(y, dtype=float)
    R = np.empty((9, y.shape[-1]))            # R(t) and r(t) from R0, r0: x_k = c x_k-1 + w0 f0 + wm fm + w1 f1
    _ewls_loops.recursion(P, y, float(w0), float(wm), float(w1), float(c),
                          np.ascontiguousarray(np.concatenate([R0[UPPER3], r0]), dtype=float), R)
    return solve_spd3(R)


def ewls_start(Phi: np.ndarray, y: np.ndarray, fs: float, init_window: float) -> tuple[np.ndarray, np.ndarray]:
    """``R0 = P(0)^-1`` and ``r0 = R0 Theta(0)`` of eq. 6 by least squares over the first ``init_window``
    seconds: ``R0 = sum of Phi Phi^T dt`` and ``r0 = sum of Phi y dt`` over that window (``dt = 1/fs``),
    so that ``Theta(0) = R0^-1 r0`` is the ordinary least-squares fit there.

    References
    ----------
    Xu & Hollerbach (1998), Sec. II-D ("initial values ... calculated using standard least squares").
    """
    m = max(int(round(init_window * fs)), 3)
    return unpack(forcing(Phi[:, :m], y[:, :m]).sum(axis=0) / fs)


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


def ewls_riccati_rk4(Phi: np.ndarray, y: np.ndarray, dt: float, lam: float, P0: np.ndarray,
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
