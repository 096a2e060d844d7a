"""The time-varying two-sided impulse response: :class:`TVIRFEstimate` (lags x time, valid samples).

Returned by the ensemble estimators (``ensemble_irf``, ``sds``, ``guarin``); see :mod:`jointbench.core.estimate`
for the common interface.
"""
from __future__ import annotations

import dataclasses
from typing import TYPE_CHECKING

import numpy as np

from jointbench.core.estimate import Estimate, Prediction

if TYPE_CHECKING:  # pragma: no cover
    import pandas as pd


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
        :func:`jointbench.core.ensemble.valid_mask`.
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

    def prediction(self, trial, index: int = 0) -> Prediction:
        """The torque (mean removed) against :meth:`predict` of the angle (mean removed), on the
        :attr:`valid` samples only (elsewhere the IRF is held from the nearest valid sample)."""
        y = trial.output - np.mean(trial.output)
        yhat = self.predict(trial.input - np.mean(trial.input))
        return Prediction(y, yhat, self.valid.copy(), "torque (mean removed) against the prediction from the "
                          "angle (mean removed), on the samples where the time-varying IRF is estimated "
                          f"({int(self.valid.sum())} of {len(self.valid)})")

    def frequency_response(self, f: np.ndarray, t=None) -> np.ndarray:
        """Frozen response ``sum_k h(k, t) exp(-j 2 pi f k / fs)``: ``(len(t), len(f))``, or ``(len(f),)``
        for a scalar ``t``."""
        if t is None:
            raise ValueError(f"{self.estimator}: the estimate is time-varying; give the time(s) t")
        w = 2 * np.pi * np.atleast_1d(np.asarray(f, float)) / self.fs
        H = (np.exp(-1j * np.outer(w, self.lags)) @ self.irf_at(t)).T
        return H[0] if np.ndim(t) == 0 else H

    def to_frame(self) -> pd.DataFrame:
        """``time``, ``stiffness`` (with ``stiffness_lo``, ``stiffness_hi`` when :attr:`intervals` has them)
        and ``valid``."""
        import pandas as pd

        frame = pd.DataFrame({"time": self.time, "stiffness": self.h.sum(axis=0), "valid": self.valid})
        return self.add_interval_columns(frame)

    def response_frame(self) -> pd.DataFrame:
        """The IRF in long form: ``time, lag, lag_s, h`` (one row per sample and lag)."""
        import pandas as pd

        n, nl = len(self.time), len(self.lags)
        return pd.DataFrame({"time": np.repeat(self.time, nl), "lag": np.tile(self.lags, n),
                             "lag_s": np.tile(self.lags / self.fs, n), "h": self.h.T.ravel()})

    def summary(self):
        out = super().summary()
        out["lags"] = f"{int(self.lags[0])} ... {int(self.lags[-1])} samples"
        out["valid"] = f"{int(self.valid.sum())} of {len(self.valid)} samples"
        out.update(self.info)
        return out
