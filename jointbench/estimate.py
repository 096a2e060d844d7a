"""Result objects returned by every estimator (one interface, no shape-dependent tuples).

An :class:`Estimate` predicts the output (torque for an imposed angle) from the input, reports the
low-frequency stiffness over time, and turns itself into tidy tables: :meth:`Estimate.to_frame` (one
row per time sample: ``time`` plus ``I``, ``B``, ``K``, ``stiffness`` where available) and
:meth:`Estimate.response_frame` (the impulse or frequency response, where there is one).
"""
from __future__ import annotations

import dataclasses
from abc import ABC, abstractmethod

import numpy as np
import pandas as pd


class Estimate(ABC):
    """Common interface of all estimates."""

    estimator: str
    time: np.ndarray
    fs: float

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
        """``time`` plus whichever of ``I``, ``B``, ``K`` exist, and ``stiffness``."""
        cols = {"time": self.time}
        cols.update(self.parameters())
        cols["stiffness"] = self.stiffness(self.time)
        return pd.DataFrame(cols)

    def response_frame(self) -> pd.DataFrame | None:
        """Impulse or frequency response as a table, or ``None``."""
        return None

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
        return pd.DataFrame({"lag": self.lags, "lag_s": self.lags / self.fs, "h": self.h})

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
        return pd.DataFrame({"freq_hz": self.freq, "re": self.H.real, "im": self.H.imag,
                             "mag": np.abs(self.H), "phase_rad": np.angle(self.H),
                             "coherence2": self.coherence})


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

    def frequency_response(self, f: np.ndarray, t=None) -> np.ndarray:
        if np.ndim(self.I) or np.ndim(self.B) or np.ndim(self.K):
            raise NotImplementedError("time-varying parameters have no single frequency response")
        w = 2 * np.pi * np.asarray(f, float)
        return self.K + 1j * w * self.B - self.I * w ** 2

    def response_frame(self) -> pd.DataFrame | None:
        return None if self.basis is None else self.basis.response_frame()


@dataclasses.dataclass(eq=False)
class TVIRFEstimate(Estimate):
    """Time-varying two-sided impulse response ``h(k, t_i)``: lags ``k = -M1 ... M2`` by sample times.

    The model is ``y(t_i) = sum_k h(k, t_i) u(t_i - k / fs)`` (zero outside the record), the frozen
    IRF at each time applied to the input around it.

    Unit convention (the same as :class:`IRFEstimate`): ``h`` is the weight of the discrete
    convolution, not scaled by the sampling interval. Toolboxes that store the IRF as a density
    ``g = h fs`` (N·m/rad/s; the REKLAB/NLID ``irf`` objects, ``tv_ident``) write the low-frequency gain
    as ``Ts sum_k g(k, t)``; here that same number is ``sum_k h(k, t)`` = :meth:`stiffness`.

    Attributes
    ----------
    lags : ndarray of int, shape (L,)
        Lags in samples, increasing, ``-M1 ... M2``.
    h : ndarray, shape (L, N)
        The IRF at every sample time.
    fs : float
        Sampling rate (Hz).
    time : ndarray, shape (N,)
        Sample times (s) of the record(s) fitted.
    valid : ndarray of bool, shape (N,)
        Samples where the IRF was estimated from data; elsewhere (record ends that the lags or a
        window do not reach) it is held from the nearest valid sample. See
        :func:`jointbench.ensemble.valid_mask`.
    estimator : str
        Name of the estimator.
    info : dict
        Numbers about the fit (realizations, orders chosen, ...), shown by :meth:`summary`.

    References
    ----------
    MacNeil, Kearney & Hunter (1992), IEEE TBME 39(12) (the ensemble time-varying IRF); Westwick &
    Perreault (2012), eq. 9 (two-sided IRF, unscaled sum).
    """

    lags: np.ndarray
    h: np.ndarray
    fs: float
    time: np.ndarray
    valid: np.ndarray
    estimator: str = "tv_irf"
    info: dict = dataclasses.field(default_factory=dict)

    def __post_init__(self):
        self.lags = np.asarray(self.lags, int)
        self.h = np.asarray(self.h, float)
        self.time = np.asarray(self.time, float)
        self.valid = np.asarray(self.valid, bool)
        if self.h.shape != (len(self.lags), len(self.time)) or self.valid.shape != self.time.shape:
            raise ValueError(f"TVIRFEstimate: h must be lags x time ({len(self.lags)} x {len(self.time)}) and valid "
                             f"one flag per sample; got h {self.h.shape}, valid {self.valid.shape}")

    @property
    def m1(self) -> int:
        """Anticipatory lags M1 (samples)."""
        return -int(self.lags[0])

    def irf_at(self, t) -> np.ndarray:
        """The IRF at times ``t`` (linear interpolation between samples, held outside): ``(L, len(t))``."""
        t = np.atleast_1d(np.asarray(t, float))
        x = (t - self.time[0]) * self.fs
        i0 = np.clip(np.floor(x).astype(int), 0, len(self.time) - 1)
        i1 = np.minimum(i0 + 1, len(self.time) - 1)
        w = np.clip(x - i0, 0.0, 1.0)
        return self.h[:, i0] * (1 - w) + self.h[:, i1] * w

    def stiffness(self, t) -> np.ndarray:
        """Low-frequency gain ``sum_k h(k, t)`` (N·m/rad) at times ``t``."""
        out = self.irf_at(t).sum(axis=0)
        return out[0] if np.ndim(t) == 0 else out.reshape(np.shape(t))

    def predict(self, u: np.ndarray) -> np.ndarray:
        """``y(t_i) = sum_k h(k, t_i) u(i - k)`` for an input on the fitted time base (zero outside it)."""
        u = np.asarray(u, float)
        n = len(self.time)
        if u.shape != (n,):
            raise ValueError(f"{self.estimator}: predict needs an input on the fitted time base ({n} samples), got "
                             f"shape {u.shape}")
        m1, m2 = self.m1, int(self.lags[-1])
        padded = np.concatenate([np.zeros(m2), u, np.zeros(m1)])
        # column j of the window at sample i holds u(i + M1 - j), i.e. lag k = j - M1
        from numpy.lib.stride_tricks import sliding_window_view
        U = sliding_window_view(padded, len(self.lags))[:, ::-1]
        return np.einsum("ij,ji->i", U, self.h)

    def frequency_response(self, f: np.ndarray, t=None) -> np.ndarray:
        """Frozen response ``sum_k h(k, t) exp(-j 2 pi f k / fs)``: ``(len(t), len(f))``, or ``(len(f),)``
        for a scalar ``t``."""
        if t is None:
            raise ValueError(f"{self.estimator}: the estimate is time-varying; give the time(s) t")
        w = 2 * np.pi * np.atleast_1d(np.asarray(f, float)) / self.fs
        H = (np.exp(-1j * np.outer(w, self.lags)) @ self.irf_at(t)).T
        return H[0] if np.ndim(t) == 0 else H

    def to_frame(self) -> pd.DataFrame:
        """``time``, ``stiffness`` and ``valid``."""
        return pd.DataFrame({"time": self.time, "stiffness": self.h.sum(axis=0), "valid": self.valid})

    def response_frame(self) -> pd.DataFrame:
        """The IRF in long form: ``time, lag, lag_s, h`` (one row per sample and lag)."""
        n, nl = len(self.time), len(self.lags)
        return pd.DataFrame({"time": np.repeat(self.time, nl), "lag": np.tile(self.lags, n),
                             "lag_s": np.tile(self.lags / self.fs, n), "h": self.h.T.ravel()})

    def summary(self):
        out = super().summary()
        out["lags"] = f"{int(self.lags[0])} ... {int(self.lags[-1])} samples"
        out["valid"] = f"{int(self.valid.sum())} of {len(self.valid)} samples"
        out.update(self.info)
        return out
