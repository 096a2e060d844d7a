"""Result objects returned by every estimator (one interface, no shape-dependent tuples).

An :class:`Estimate` predicts the output (torque for an imposed angle) from the input, reports the
low-frequency stiffness over time, and turns itself into tidy tables: :meth:`Estimate.to_frame` (one
row per time sample: ``time`` plus ``I``, ``B``, ``K``, ``stiffness`` where available) and
:meth:`Estimate.response_frame` (the impulse or frequency response, where there is one).

Two optional parts, for estimators that provide them:

* :attr:`Estimate.intervals`, an :class:`Intervals`: confidence intervals of the parameters and the
  stiffness (``*_lo``, ``*_hi`` columns of :meth:`~Estimate.to_frame`) and of the response
  (``*_lo``, ``*_hi`` columns of :meth:`~Estimate.response_frame`);
* :attr:`Estimate.fit_info`: numbers about the fit worth printing (chosen regularisation, ...).

:meth:`Estimate.prediction` says what the estimate's VAF is computed on (a :class:`Prediction`).
"""
from __future__ import annotations

import dataclasses
import types
from abc import ABC, abstractmethod
from typing import TYPE_CHECKING, Callable, Mapping

import numpy as np

# pandas is imported where a table is made: importing this module stays cheap (jointbench estimate --list)
if TYPE_CHECKING:  # pragma: no cover
    import pandas as pd

from jointbench.core import band
from jointbench.core.errors import InputError
from jointbench.core.scores import vaf

_EMPTY: Mapping = types.MappingProxyType({})


@dataclasses.dataclass(frozen=True, eq=False)
class Intervals:
    """Confidence intervals of an estimate, all at one level.

    Attributes
    ----------
    level : float
        Confidence level, e.g. 0.95.
    method : str
        How they were computed (printed in the summary), e.g. "segment-robust covariance".
    bounds : mapping of str to (lo, hi)
        Per quantity of :meth:`Estimate.to_frame` (``"I"``, ``"B"``, ``"K"``, ``"stiffness"``): lower
        and upper limits, scalars (time-invariant) or arrays on :attr:`Estimate.time` (pointwise bands).
    response : mapping of str to (lo, hi)
        Per column of :meth:`Estimate.response_frame` (e.g. ``"h"``, ``"mag"``): row-aligned limits.
    pointwise : bool
        True when the bounds are pointwise (each time or lag on its own), not simultaneous.
    """

    level: float
    method: str
    bounds: Mapping[str, tuple] = dataclasses.field(default_factory=dict)
    response: Mapping[str, tuple] = dataclasses.field(default_factory=dict)
    pointwise: bool = True


@dataclasses.dataclass(frozen=True, eq=False)
class Prediction:
    """The measured output and the estimate's prediction of it, on which the VAF is computed.

    Attributes
    ----------
    y, yhat : ndarray
        Measured and predicted output of one record, as compared (e.g. means removed, band-limited).
    used : ndarray of bool
        Samples entering the VAF (e.g. not the record ends the prediction cannot reach).
    definition : str
        What ``y`` and ``yhat`` are, in a few words (printed beside the VAF).
    """

    y: np.ndarray
    yhat: np.ndarray
    used: np.ndarray
    definition: str

    def vaf(self) -> float:
        """The VAF (:func:`jointbench.core.scores.vaf`) of :attr:`yhat` against :attr:`y` over the
        :attr:`used` samples, in percent.

        Raises
        ------
        InputError
            The VAF is undefined there: fewer than 2 samples used, a non-finite value, or no variance in
            ``y`` (a constant or zero torque: nothing to explain).
        """
        return vaf(self.y[self.used], self.yhat[self.used])


class Estimate(ABC):
    """Common interface of all estimates."""

    estimator: str
    time: np.ndarray
    fs: float
    #: confidence intervals, an :class:`Intervals` or a function computing them on first use (set by the
    #: estimator after fitting: :meth:`with_intervals`), or None when the estimator gives none
    _intervals: Intervals | Callable[[], Intervals | None] | None = None
    #: numbers about the fit worth printing (regularisation chosen, ...), shown by :meth:`summary`
    fit_info: Mapping[str, object] = _EMPTY
    #: (low, high) band (Hz) the estimate rests on, set by estimators that fit over a band (columns
    #: ``band_lo_hz``, ``band_hi_hz`` of :meth:`to_frame`); None = not stated
    band_hz: tuple[float, float] | None = None

    @abstractmethod
    def predict(self, u: np.ndarray) -> np.ndarray:
        """Output predicted for input ``u`` (same sampling rate as the data it was fitted on)."""

    @abstractmethod
    def stiffness(self, t: np.ndarray | float) -> np.ndarray:
        """Low-frequency stiffness (N·m/rad) at times ``t``."""

    def parameters(self) -> dict[str, np.ndarray]:
        """Time courses of I, B, K on :attr:`time` (empty when the estimate is nonparametric)."""
        return {}

    def to_frame(self) -> pd.DataFrame:
        """``time`` plus whichever of ``I``, ``B``, ``K`` exist, and ``stiffness``; each followed by its
        ``*_lo``, ``*_hi`` confidence limits when :attr:`intervals` has them; then ``band_lo_hz``,
        ``band_hi_hz`` when :attr:`band_hz` is set (the band a CSV's numbers hold in)."""
        import pandas as pd
        cols = {"time": self.time}
        cols.update(self.parameters())
        cols["stiffness"] = self.stiffness(self.time)
        return self.add_band_columns(self.add_interval_columns(pd.DataFrame(cols)))

    def add_band_columns(self, frame: pd.DataFrame) -> pd.DataFrame:
        """``frame`` with columns ``band_lo_hz``, ``band_hi_hz`` (:attr:`band_hz`) when it is set."""
        if self.band_hz is not None:
            frame["band_lo_hz"], frame["band_hi_hz"] = float(self.band_hz[0]), float(self.band_hz[1])
        return frame

    def response_frame(self) -> pd.DataFrame | None:
        """Impulse or frequency response as a table, or ``None``."""
        return None

    @property
    def intervals(self) -> Intervals | None:
        """Confidence intervals, or None when the estimator gives none (computed on first use when the
        estimator attached a function: a harness that scores only the estimate pays nothing for them)."""
        iv = self._intervals
        if callable(iv):
            iv = self._intervals = iv()
        return iv

    def with_intervals(self, intervals: Intervals | Callable[[], Intervals | None] | None) -> "Estimate":
        """Attach ``intervals``, or a function without arguments that computes them when first asked for
        (returns ``self``)."""
        self._intervals = intervals
        return self

    def add_interval_columns(self, frame: pd.DataFrame, response: bool = False) -> pd.DataFrame:
        """Insert ``<col>_lo``, ``<col>_hi`` after every column of ``frame`` that :attr:`intervals` bounds.

        ``response=False``: the per-sample bounds (:attr:`Intervals.bounds`, scalars broadcast);
        ``response=True``: the response bounds (:attr:`Intervals.response`).
        """
        import pandas as pd
        iv = self.intervals
        if iv is None:
            return frame
        bounds = iv.response if response else iv.bounds
        out = {}
        for col in frame.columns:
            out[col] = frame[col].to_numpy()
            if col in bounds:
                lo, hi = bounds[col]
                out[f"{col}_lo"] = np.broadcast_to(np.asarray(lo, float), (len(frame),))
                out[f"{col}_hi"] = np.broadcast_to(np.asarray(hi, float), (len(frame),))
        return pd.DataFrame(out, index=frame.index)

    def prediction(self, trial, index: int = 0) -> Prediction:
        """What the VAF of record ``trial`` (the ``index``-th record fitted) is computed on.

        Default: ``y`` = the output minus its mean, ``yhat`` = :meth:`predict` of the input minus its
        mean, every sample. Estimates whose prediction is only defined on part of a record, or that
        fit a filtered output, override it.
        """
        y = trial.output - np.mean(trial.output)
        yhat = np.asarray(self.predict(trial.input - np.mean(trial.input)), float)
        return Prediction(y, yhat, np.ones(len(y), bool),
                          "torque (mean removed) against the prediction from the angle (mean removed), "
                          "every sample")

    def frequency_response(self, f: np.ndarray, t: np.ndarray | float | None = None) -> np.ndarray:
        """Complex frequency response (input -> output) at frequencies ``f`` (Hz).

        Time-varying estimates return the frozen response at time(s) ``t`` (s): shape ``(len(t), len(f))``
        for an array ``t``, ``(len(f),)`` for a scalar; ``t=None`` is only allowed when the estimate is
        time-invariant (then ``t`` is ignored).
        """
        raise NotImplementedError(f"{type(self).__name__} has no frequency response")

    def summary(self) -> dict[str, float | str]:
        """A few numbers worth printing."""
        out: dict[str, float | str] = {"estimator": self.estimator, "fs_hz": self.fs}
        for k, v in self.parameters().items():
            out[k] = float(np.mean(v))
        out["stiffness"] = float(np.mean(self.stiffness(self.time)))
        out.update(self.fit_info)
        return out


def _const(v: float, t) -> np.ndarray:
    return np.full(np.shape(t), float(v))


@dataclasses.dataclass(eq=False)
class IRFEstimate(Estimate):
    """Two-sided impulse response ``h(k)``, lags ``k = -M1 ... M2`` samples.

    The convolution is not scaled by the sampling increment: ``y(t) = sum_k h(k) u(t - k)``
    (Westwick & Perreault 2012, eq. 9 with the sum over -M1 ... M2).
    """

    lags: np.ndarray
    h: np.ndarray
    fs: float
    time: np.ndarray
    estimator: str = "irf"

    def predict(self, u: np.ndarray) -> np.ndarray:
        u = np.asarray(u, float)
        m1 = -int(self.lags[0])
        full = np.convolve(u, self.h)
        return full[m1:m1 + len(u)]

    def frequency_response(self, f: np.ndarray, t=None) -> np.ndarray:
        w = 2 * np.pi * np.asarray(f, float)[..., None] / self.fs
        return np.exp(-1j * w * self.lags) @ self.h

    def stiffness(self, t) -> np.ndarray:
        return _const(np.sum(self.h), t)

    def response_frame(self) -> pd.DataFrame:
        """``lag``, ``lag_s``, ``h`` (and ``h_lo``, ``h_hi`` with intervals)."""
        import pandas as pd
        frame = pd.DataFrame({"lag": self.lags, "lag_s": self.lags / self.fs, "h": self.h})
        return self.add_interval_columns(frame, response=True)

    def prediction(self, trial, index: int = 0) -> Prediction:
        """The IRF's prediction where it is defined: the samples whose lags ``-M1 ... M2`` all lie in the
        record (the first ``M2`` and last ``M1`` samples are dropped: their prediction would need angle
        samples from outside the record)."""
        base = super().prediction(trial, index)
        m1, m2 = -int(self.lags[0]), int(self.lags[-1])
        used = np.zeros(len(base.y), bool)
        used[max(m2, 0):len(used) - max(m1, 0)] = True
        return dataclasses.replace(base, used=used, definition=(
            "torque (mean removed) against the IRF's prediction from the angle (mean removed), on the "
            f"samples whose lags all lie in the record (first {max(m2, 0)} and last {max(m1, 0)} dropped)"))

    def summary(self):
        out = super().summary()
        out["lags"] = f"{int(self.lags[0])} ... {int(self.lags[-1])} samples"
        return out


@dataclasses.dataclass(eq=False)
class FRFEstimate(Estimate):
    """Nonparametric frequency response at ``freq`` (Hz, 0 ... fs/2) with squared coherence."""

    freq: np.ndarray
    H: np.ndarray
    coherence: np.ndarray
    fs: float
    time: np.ndarray
    estimator: str = "frf"
    #: effective number of independent spectral averages (None: unknown; every frequency is then used)
    n_averages: float | None = None
    #: the input's (angle's) power spectral density at ``freq`` (None: unknown), for the input's band
    #: (:func:`jointbench.core.band.input_band`)
    input_power: np.ndarray | None = None

    def significant(self) -> np.ndarray:
        """Frequencies whose squared coherence is significantly above zero
        (:func:`jointbench.core.band.significant` for :attr:`n_averages`: under zero coherence the squared
        coherence of ``n`` independent averages exceeds ``1 - 0.05^(1/(n - 1))`` with probability 0.05,
        Carter, Knapp & Nuttall 1973; with ``n_averages`` unknown or below 2, every frequency with nonzero
        coherence)."""
        return band.significant(self.coherence, self.n_averages)

    def segment_samples(self) -> int:
        """Length (samples) of the segments ``H`` was estimated on: ``fs / freq[1]``."""
        f = np.asarray(self.freq, float)
        return int(round(self.fs / f[1])) if len(f) > 1 and f[1] > 0 else 2 * (len(f) - 1)

    def excited(self) -> np.ndarray:
        """The excited frequencies (:func:`jointbench.core.band.excited`: input power and significant
        coherence), the one definition every band check uses."""
        return band.excited(self.input_power, self.coherence, self.n_averages)

    def prediction(self, trial, index: int = 0) -> Prediction:
        """Prediction with ``H`` only at the excited frequencies (:meth:`excited`).

        The angle's DFT over the record is multiplied by ``H`` interpolated linearly between its
        frequencies, with ``H = 0`` at the frequencies not excited (the input has no power there, or the
        coherence is not significant: ``H`` there is noise, however large) and at DC the real part at the
        lowest frequency. The product is circular, so half a segment
        (:meth:`segment_samples`) is left out at each end of the record.
        """
        y = trial.output - np.mean(trial.output)
        u = trial.input - np.mean(trial.input)
        n = len(u)
        Hs = np.where(self.excited(), self.H, 0.0)
        fr = np.fft.rfftfreq(n, 1.0 / self.fs)
        Hr = np.interp(fr, self.freq, Hs.real) + 1j * np.interp(fr, self.freq, Hs.imag)
        lowest = Hs[1] if len(Hs) > 1 else Hs[0]
        Hr[fr < (self.freq[1] if len(self.freq) > 1 else np.inf)] = lowest.real
        if n % 2 == 0:
            Hr[-1] = Hr[-1].real
        yhat = np.fft.irfft(np.fft.rfft(u) * Hr, n)
        edge = self.segment_samples() // 2
        used = np.zeros(n, bool)
        used[edge:n - edge] = True
        if not used.any():
            raise InputError(f"record '{trial.name}' ({n} samples) is not longer than one segment "
                             f"({2 * edge} samples) of the frequency response")
        return Prediction(y, yhat, used, "torque (mean removed) against the prediction from the angle (mean "
                          "removed) with H only at the excited frequencies (input power, coherence significant "
                          "at 95 %), "
                          f"without the first and last {edge} samples (half a segment)")

    def frequency_response(self, f: np.ndarray, t=None) -> np.ndarray:
        f = np.asarray(f, float)
        return np.interp(f, self.freq, self.H.real) + 1j * np.interp(f, self.freq, self.H.imag)

    def predict(self, u: np.ndarray) -> np.ndarray:
        u = np.asarray(u, float)
        n = len(u)
        f = np.fft.rfftfreq(n, 1.0 / self.fs)
        return np.fft.irfft(np.fft.rfft(u) * self.frequency_response(f), n)

    def stiffness(self, t) -> np.ndarray:
        """|H| at the lowest positive frequency estimated."""
        i = int(np.argmax(self.freq > 0))
        return _const(abs(self.H[i]), t)

    def response_frame(self) -> pd.DataFrame:
        """``freq_hz, re, im, mag, phase_rad, coherence2, significant`` (and the ``*_lo``, ``*_hi``
        limits of ``mag`` and ``phase_rad`` with intervals)."""
        import pandas as pd
        frame = pd.DataFrame({"freq_hz": self.freq, "re": self.H.real, "im": self.H.imag,
                              "mag": np.abs(self.H), "phase_rad": np.angle(self.H),
                              "coherence2": self.coherence, "significant": self.significant()})
        return self.add_interval_columns(frame, response=True)


@dataclasses.dataclass(eq=False)
class ParametricEstimate(Estimate):
    """Second-order impedance ``tau = I theta'' + B theta' + K theta``.

    ``I``, ``B``, ``K`` are scalars (time-invariant) or arrays on :attr:`time` (time-varying).
    ``basis`` optionally keeps the nonparametric estimate the parameters were fitted to.
    """

    I: float | np.ndarray
    B: float | np.ndarray
    K: float | np.ndarray
    fs: float
    time: np.ndarray
    estimator: str = "parametric"
    basis: Estimate | None = None
    #: (low, high) band (Hz) the parameters were fitted in; None = up to the Nyquist frequency
    band_hz: tuple[float, float] | None = None

    def _on(self, v, t):
        return _const(v, t) if np.ndim(v) == 0 else np.interp(t, self.time, v)

    def parameters(self) -> dict[str, np.ndarray]:
        return {k: self._on(getattr(self, k), self.time) for k in ("I", "B", "K")}

    def stiffness(self, t) -> np.ndarray:
        return self._on(self.K, t)

    def predict(self, u: np.ndarray) -> np.ndarray:
        """Torque from angle with central-difference derivatives (second order accurate)."""
        u = np.asarray(u, float)
        dt = 1.0 / self.fs
        du = np.gradient(u, dt, edge_order=2)
        ddu = np.gradient(du, dt, edge_order=2)
        n = len(u)
        t = self.time[:n] if len(self.time) >= n else np.arange(n) / self.fs
        p = {k: self._on(getattr(self, k), t) for k in ("I", "B", "K")}
        return p["I"] * ddu + p["B"] * du + p["K"] * u

    def prediction(self, trial, index: int = 0) -> Prediction:
        """Time-invariant I, B, K: the model's torque in the band it was fitted in.

        Angle and torque (means removed) are low-passed alike, zero phase, by the squared magnitude of
        a 4th-order Butterworth at the band's top (:attr:`band_hz`; 0.8 of the Nyquist frequency when
        the fit used the whole band), and the model ``K + j w B - I w^2`` is applied to the angle in the
        frequency domain (exact derivatives of the band-limited angle; each end extended by its mirror
        image). Samples within ``2 fs / f_top`` of either end are left out. Time-varying parameters: the
        default of :class:`Estimate` (central-difference derivatives).
        """
        if np.ndim(self.I) or np.ndim(self.B) or np.ndim(self.K):
            return super().prediction(trial, index)
        fs = self.fs
        top = 0.8 * fs / 2 if self.band_hz is None else min(float(self.band_hz[1]), 0.8 * fs / 2)
        y = trial.output - np.mean(trial.output)
        u = trial.input - np.mean(trial.input)
        n = len(y)
        pad = min(n - 1, int(np.ceil(4 * fs / top)))
        ext = lambda x: np.concatenate([x[pad:0:-1], x, x[-2:-pad - 2:-1]])  # noqa: E731 (mirror ends)
        m = n + 2 * pad
        f = np.fft.rfftfreq(m, 1.0 / fs)
        g2 = 1.0 / (1.0 + (f / top) ** 8)       # |Butterworth 4th order|^2: zero phase
        w = 2 * np.pi * f
        Z = self.K + 1j * w * self.B - self.I * w ** 2
        yf = np.fft.irfft(np.fft.rfft(ext(y)) * g2, m)[pad:pad + n]
        yhat = np.fft.irfft(np.fft.rfft(ext(u)) * g2 * Z, m)[pad:pad + n]
        edge = int(np.ceil(2 * fs / top))
        used = np.zeros(n, bool)
        used[edge:n - edge] = True
        if not used.any():
            used[:] = True
        return Prediction(yf, yhat, used, "torque against the I-B-K model's torque from the angle (means "
                          f"removed), both low-passed to {top:.4g} Hz (the fitted band; zero phase), "
                          f"without the first and last {edge} samples")

    def frequency_response(self, f: np.ndarray, t=None) -> np.ndarray:
        if np.ndim(self.I) or np.ndim(self.B) or np.ndim(self.K):
            raise NotImplementedError("time-varying parameters have no single frequency response")
        w = 2 * np.pi * np.asarray(f, float)
        return self.K + 1j * w * self.B - self.I * w ** 2

    def response_frame(self) -> pd.DataFrame | None:
        return None if self.basis is None else self.basis.response_frame()


# ------------------------------------------------------------------------------------------------ validation
def estimate_problem(estimate, lengths, fs: float) -> str | None:
    """What is wrong with ``estimate`` as the result of a fit of records of ``lengths`` samples at ``fs`` Hz
    (a few words), or None: not an :class:`Estimate`; a time base that is not one sample per sample of a
    fitted record, or at another rate; a parameter that is neither a scalar nor one value per sample of the
    time base; a stiffness of another shape. Checked by :meth:`jointbench.estimators.Estimator.fit` for every
    estimator, built-in or plugin, before any caller sees the estimate (values: :func:`non_finite`)."""
    if not isinstance(estimate, Estimate):
        return f"returned {type(estimate).__name__}, not an Estimate (jointbench.core.estimate)"
    time = np.asarray(getattr(estimate, "time", None))
    if time.ndim != 1 or time.dtype.kind not in "iuf":
        return f"its time base is not a 1-D array of seconds (shape {time.shape}, dtype {time.dtype})"
    if len(time) not in set(lengths):
        return (f"its time base has {len(time)} samples, the data {' or '.join(str(n) for n in sorted(set(lengths)))}"
                f" (one value per sample of the fitted record)")
    if not np.isclose(float(getattr(estimate, "fs", np.nan)), fs, rtol=1e-9):
        return f"its sampling rate is {getattr(estimate, 'fs', None)!r} Hz, the data's {fs:g} Hz"
    for key in ("I", "B", "K"):                 # a parametric estimate's own arrays, before they are evaluated
        shape = np.shape(getattr(estimate, key, 0.0))
        if shape not in ((), (len(time),)):
            return f"its {key} has shape {shape}, not a scalar or one value per sample of the time base ({len(time)},)"
    try:
        params = estimate.parameters()
        stiffness = np.asarray(estimate.stiffness(time))
    except Exception as exc:  # noqa: BLE001 - a plugin's estimate may fail in any way: one line, not a traceback
        return f"its parameters cannot be evaluated on its time base ({type(exc).__name__}: {exc})"
    for key, value in {**params, "stiffness": stiffness}.items():
        shape = np.shape(value)
        if shape not in ((), (len(time),)):
            return (f"its {key} has shape {shape}, not a scalar or one value per sample of the time base "
                    f"({len(time)},)")
    return None


def non_finite(estimate: Estimate, bounds: bool = True) -> list[str]:
    """The quantities of ``estimate`` holding a value that is not finite (NaN or infinite: what the data do
    not determine): its parameters, stiffness and, with ``bounds``, their interval limits (``K_lo``, ``K_hi``,
    as :meth:`Estimate.to_frame` names them; computed then if the estimator computes them on first use),
    read directly, without building the table."""
    values = {**estimate.parameters(), "stiffness": estimate.stiffness(estimate.time)}
    iv = estimate.intervals if bounds else None
    for key, (lo, hi) in (iv.bounds.items() if iv is not None else ()):
        values[f"{key}_lo"], values[f"{key}_hi"] = lo, hi
    return [k for k, v in values.items() if not np.all(np.isfinite(np.asarray(v, float)))]


def degenerate_intervals(estimate: Estimate) -> dict[str, float]:
    """The quantities whose confidence interval (:attr:`Intervals.bounds`) has, somewhere on the time base,
    a width that is zero (to rounding: 1e-9 of the bound), negative or not finite: quantity -> its smallest
    width (NaN when not finite). An interval of zero width claims an exact value; no estimate from noisy
    data has one. Empty when the estimate has no intervals."""
    iv = estimate.intervals
    if iv is None:
        return {}
    out: dict[str, float] = {}
    for key, (lo, hi) in iv.bounds.items():
        lo, hi = np.asarray(lo, float), np.asarray(hi, float)
        width = hi - lo
        if not np.all(np.isfinite(width)):
            out[key] = float("nan")
        elif np.any(width <= 1e-9 * np.maximum(np.abs(lo), np.abs(hi))):     # zero to rounding
            out[key] = float(np.min(width))
    return out
