"""Figures of an estimate for ``jointbench estimate --plot`` (matplotlib, Agg, no pyplot state).

:func:`plot_estimate` picks the layout from the estimate:

* :class:`~jointbench.core.estimate.IRFEstimate`: the impulse response ``h`` against lag (s).
* :class:`~jointbench.core.estimate.FRFEstimate`: gain, phase and squared coherence against frequency.
* :class:`~jointbench.core.estimate.ParametricEstimate` with constant I, B, K: its basis (IRF or FRF, when
  kept; an IRF is drawn against lag and as a frequency response) overlaid with the I-B-K model's
  frequency response ``K + j w B - I w^2``; I, B, K in the title.
* time-varying parameters: I(t), B(t), K(t).
* anything else: the stiffness over time.

Confidence intervals (:attr:`~jointbench.core.estimate.Estimate.intervals`) are drawn as shaded bands
(95 %): the IRF's pointwise band, the FRF's gain and phase band from the coherence, the pointwise
bands of I(t), B(t), K(t) or of the stiffness; the I-B-K title gives the parameters' intervals.
"""
from __future__ import annotations

from pathlib import Path
from typing import Sequence

import numpy as np
from matplotlib.figure import Figure

from jointbench.core.estimate import Estimate, FRFEstimate, IRFEstimate, ParametricEstimate
from jointbench.core.types import Trial

_LABELS = {"I": "I (kg m²)", "B": "B (N m s/rad)", "K": "K (N m/rad)"}
_BAND = {"alpha": 0.25, "lw": 0}


def _band(ax, x, est: Estimate, key: str, response: bool = False, transform=None, label: bool = True) -> None:
    """Shade ``est``'s interval of ``key`` over ``x`` (a parameter, or a response column), if it has one."""
    iv = est.intervals
    bounds = None if iv is None else (iv.response if response else iv.bounds).get(key)
    if bounds is None:
        return
    lo, hi = (np.broadcast_to(np.asarray(b, float), np.shape(x)) for b in bounds)
    if transform is not None:
        lo, hi = transform(lo), transform(hi)
    ax.fill_between(x, lo, hi, label=f"{100 * iv.level:g} % interval" if label else None, **_BAND)


def plot_estimate(est: Estimate, path: str | Path, trials: Sequence[Trial] | None = None,
                  fmt: str | None = None) -> None:
    """Draw ``est`` and save it to ``path``.

    Parameters
    ----------
    est : Estimate
        The estimate to draw.
    path : str or Path
        Output file.
    trials : sequence of Trial, optional
        The records the estimate was fitted on (named in the title).
    fmt : str, optional
        File format (``"png"``, ``"pdf"``, ``"svg"``); default from the suffix of ``path``.
    """
    fig = make_figure(est, trials)
    fig.savefig(path, format=fmt, dpi=120)


def make_figure(est: Estimate, trials: Sequence[Trial] | None = None) -> Figure:
    """The figure :func:`plot_estimate` saves."""
    fig = Figure(figsize=(7.5, 7.5), layout="constrained")
    names = ", ".join(t.name for t in trials) if trials else ""
    title = f"{est.estimator}" + (f" on {names}" if names else "")
    if isinstance(est, ParametricEstimate):
        if any(np.ndim(getattr(est, k)) for k in "IBK"):
            _time_varying(fig, est)
        else:
            _parametric(fig, est)
            title += "\n" + ", ".join(_value_text(est, k) for k in "IBK")
    elif isinstance(est, IRFEstimate):
        fig.set_size_inches(7.5, 4.0)
        _irf(fig.add_subplot(), est)
        title += f"\nlow-frequency stiffness sum(h) = {_value_text(est, 'stiffness', float(np.sum(est.h)))}"
    elif isinstance(est, FRFEstimate):
        _frf(fig, est)
    else:
        fig.set_size_inches(7.5, 4.0)
        ax = fig.add_subplot()
        ax.plot(est.time, est.stiffness(est.time), label="stiffness")
        _band(ax, est.time, est, "stiffness")
        ax.set(xlabel="time (s)", ylabel="stiffness (N m/rad)")
        if est.intervals is not None:
            ax.legend(fontsize=8)
    fig.suptitle(title, fontsize=10)
    return fig


def _value_text(est: Estimate, key: str, value: float | None = None) -> str:
    """``K = 102.9 [101.2, 104.6]`` (the interval when the estimate has one)."""
    v = float(getattr(est, key)) if value is None else value
    text = f"{key} = {v:.4g}"
    if est.intervals is not None and key in est.intervals.bounds:
        lo, hi = (float(np.mean(b)) for b in est.intervals.bounds[key])
        text += f" [{lo:.4g}, {hi:.4g}]"
    return text


def _irf(ax, est: IRFEstimate, label: str = "IRF") -> None:
    lag_s = est.lags / est.fs
    ax.axhline(0.0, color="0.7", lw=0.8)
    ax.plot(lag_s, est.h, "o-", ms=3, lw=1, label=label)
    _band(ax, lag_s, est, "h", response=True)
    ax.set(xlabel="lag (s)", ylabel="h (N m/rad per sample)")
    if est.intervals is not None:
        ax.legend(fontsize=8)


def _gain_phase(fig, n_rows: int):
    axes = fig.subplots(n_rows, 1, sharex=True)
    axes[0].set(ylabel="gain (N m/rad)", xscale="log", yscale="log")
    axes[1].set(ylabel="phase (deg)")
    axes[-1].set(xlabel="frequency (Hz)")
    return axes


def _frf(fig, est: FRFEstimate) -> None:
    ax = _gain_phase(fig, 3)
    f = np.asarray(est.freq)
    pos = f > 0
    ax[0].plot(f[pos], np.abs(est.H[pos]), label="|H|")
    _frf_bands(ax, est, pos)
    ax[1].plot(f[pos], np.degrees(np.angle(est.H[pos])))
    ax[2].plot(f[pos], np.asarray(est.coherence)[pos])
    ax[2].set(ylabel="coherence²", ylim=(0, 1.05))


def _frf_bands(ax, est: FRFEstimate, pos: np.ndarray) -> None:
    """Gain and phase bands of an FRF (where finite and positive, for the log axes)."""
    iv = est.intervals
    if iv is None or "mag" not in iv.response:
        return
    f = np.asarray(est.freq)[pos]
    lo, hi = (np.asarray(b, float)[pos] for b in iv.response["mag"])
    ok = np.isfinite(hi)
    ax[0].fill_between(f[ok], np.maximum(lo[ok], 1e-3 * np.abs(est.H[pos][ok])), hi[ok],
                       label=f"{100 * iv.level:g} % band (coherence)", **_BAND)
    plo, phi = (np.degrees(np.asarray(b, float)[pos]) for b in iv.response["phase_rad"])
    ax[1].fill_between(f[ok], plo[ok], phi[ok], **_BAND)
    ax[0].legend(fontsize=8)


def _parametric(fig, est: ParametricEstimate) -> None:
    basis = est.basis
    model = "I-B-K model"
    if isinstance(basis, IRFEstimate):
        axes = fig.subplots(3, 1)
        _irf(axes[0], basis, label=f"{basis.estimator} IRF")
        axes[0].legend(fontsize=8)
        f = np.geomspace(basis.fs / 500, basis.fs / 2, 300)
        gain, phase = axes[1], axes[2]
        gain.set(ylabel="gain (N m/rad)", xscale="log", yscale="log")
        phase.set(ylabel="phase (deg)", xscale="log", xlabel="frequency (Hz)")
        phase.sharex(gain)
        H = basis.frequency_response(f)
        gain.plot(f, np.abs(H), label=f"{basis.estimator} IRF")
        phase.plot(f, np.degrees(np.angle(H)))
    elif isinstance(basis, FRFEstimate):
        axes = _gain_phase(fig, 3)
        fb = np.asarray(basis.freq)
        pos = fb > 0
        axes[0].plot(fb[pos], np.abs(basis.H[pos]), label=f"{basis.estimator} FRF")
        _frf_bands(axes, basis, pos)
        axes[1].plot(fb[pos], np.degrees(np.angle(basis.H[pos])))
        axes[2].plot(fb[pos], np.asarray(basis.coherence)[pos])
        axes[2].set(ylabel="coherence²", ylim=(0, 1.05))
        f = fb[pos]
        gain, phase = axes[0], axes[1]
    else:
        gain, phase = _gain_phase(fig, 2)
        f = np.geomspace(est.fs / 500, est.fs / 2, 300)
    Z = est.frequency_response(f)
    gain.plot(f, np.abs(Z), "--", label=model)
    phase.plot(f, np.degrees(np.angle(Z)), "--")
    gain.legend(fontsize=8)


def _time_varying(fig, est: ParametricEstimate) -> None:
    axes = fig.subplots(3, 1, sharex=True)
    params = est.parameters()
    for ax, k in zip(axes, "IBK"):
        ax.plot(est.time, params[k])
        _band(ax, est.time, est, k, label=k == "I")
        ax.set(ylabel=_LABELS[k])
    if est.intervals is not None:
        axes[0].legend(fontsize=8, loc="upper right")
    axes[-1].set(xlabel="time (s)")
