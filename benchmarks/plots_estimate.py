"""Figures of an estimate for ``jointbench estimate --plot`` (matplotlib, Agg, no pyplot state).

:func:`plot_estimate` picks the layout from the estimate:

* :class:`~jointbench.estimate.IRFEstimate`: the impulse response ``h`` against lag (s).
* :class:`~jointbench.estimate.FRFEstimate`: gain, phase and squared coherence against frequency.
* :class:`~jointbench.estimate.ParametricEstimate` with constant I, B, K: its basis (IRF or FRF, when
  kept; an IRF is drawn against lag and as a frequency response) overlaid with the I-B-K model's
  frequency response ``K + j w B - I w^2``; I, B, K in the title.
* time-varying parameters: I(t), B(t), K(t).
* anything else: the stiffness over time.
"""
from __future__ import annotations

from pathlib import Path
from typing import Sequence

import numpy as np
from matplotlib.figure import Figure

from jointbench.estimate import Estimate, FRFEstimate, IRFEstimate, ParametricEstimate
from jointbench.types import Trial

_LABELS = {"I": "I (kg m²)", "B": "B (N m s/rad)", "K": "K (N m/rad)"}


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
            title += "\n" + ", ".join(f"{k} = {float(getattr(est, k)):.4g}" for k in "IBK")
    elif isinstance(est, IRFEstimate):
        fig.set_size_inches(7.5, 4.0)
        _irf(fig.add_subplot(), est)
        title += f"\nlow-frequency stiffness sum(h) = {float(np.sum(est.h)):.4g} N m/rad"
    elif isinstance(est, FRFEstimate):
        _frf(fig, est)
    else:
        fig.set_size_inches(7.5, 4.0)
        ax = fig.add_subplot()
        ax.plot(est.time, est.stiffness(est.time))
        ax.set(xlabel="time (s)", ylabel="stiffness (N m/rad)")
    fig.suptitle(title, fontsize=10)
    return fig


def _irf(ax, est: IRFEstimate, label: str = "IRF") -> None:
    lag_s = est.lags / est.fs
    ax.axhline(0.0, color="0.7", lw=0.8)
    ax.plot(lag_s, est.h, "o-", ms=3, lw=1, label=label)
    ax.set(xlabel="lag (s)", ylabel="h (N m/rad per sample)")


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
    ax[0].plot(f[pos], np.abs(est.H[pos]))
    ax[1].plot(f[pos], np.degrees(np.angle(est.H[pos])))
    ax[2].plot(f[pos], np.asarray(est.coherence)[pos])
    ax[2].set(ylabel="coherence²", ylim=(0, 1.05))


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
        ax.set(ylabel=_LABELS[k])
    axes[-1].set(xlabel="time (s)")
