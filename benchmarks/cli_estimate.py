"""The ``jointbench estimate`` subcommand: identify joint impedance from recorded angle and torque.

::

    jointbench estimate --estimator NAME --input FILE [--input FILE ...] --output OUT.csv
                        [--set key=value ...] [--decimate Q] [--array NAME] [--fs HZ]
                        [--torque-sign {1,-1}] [--plot FIG.png] [--list]

Reads the records (:mod:`benchmarks.io`), optionally negates the torque and decimates them, fits them together with the
estimator, writes ``OUT.csv`` (:meth:`~jointbench.estimate.Estimate.to_frame`) and, when the estimate
has an impulse or frequency response, ``OUT_irf.csv`` or ``OUT_frf.csv`` beside it, and prints a
summary. User errors raise :class:`~jointbench.errors.JointBenchError`; the top-level CLI prints
them and exits with status 2. See ``docs/estimate.md``.
"""
from __future__ import annotations

import argparse
import dataclasses
import os
from pathlib import Path
from typing import Sequence

import numpy as np

from benchmarks import io, io_ensemble
from benchmarks.metrics import vaf
from jointbench.ensemble import Ensemble
from jointbench.errors import ConfigError, InputError
from jointbench.estimate import Estimate, FRFEstimate, IRFEstimate, ParametricEstimate
from jointbench.files import atomic_write
from jointbench.schema import describe, parse_assignments
from jointbench.signal import resample_trial
from jointbench.types import Trial

PLOT_SUFFIXES = (".png", ".pdf", ".svg")
UNITS = {"I": "kg m^2", "B": "N m s/rad", "K": "N m/rad", "stiffness": "N m/rad"}

_EPILOG = """\
inputs: CSV with a header naming columns time, angle, torque (s, rad, N m; other columns ignored);
NPZ or MATLAB .mat with variables time, angle, torque; or an N x 2 [angle, torque] array of an
NPZ/.mat file chosen by --array NAME or FILE:NAME, sampled at the file's scalar 'fs' or --fs.
Several --input are records of one condition, fitted together. Ensembles (realizations of one
time-varying condition, aligned in time): an NPZ/.mat file whose angle and torque are 2-D (samples x
realizations) with fs or time, or several --input records of equal length and rate with --ensemble
(automatic for estimators that take ensembles only). IRF estimates go to OUT_irf.csv in long form.

example:
  jointbench estimate -e ibk_irf -i ankle.npz:z_pf --decimate 10 --torque-sign -1 \\
      --set lag_before=40ms --set lag_after=40ms --set bandlimit=20Hz -o out/pf.csv --plot out/pf.png
"""


def add_parser(subparsers) -> None:
    """Add the ``estimate`` subcommand to an :mod:`argparse` subparsers object."""
    p = subparsers.add_parser(
        "estimate", help="identify joint impedance from recorded angle and torque",
        description="Fit a registered estimator to recorded joint angle (input) and torque "
                    "(output) and write the estimate as CSV.",
        epilog=_EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--estimator", "-e", metavar="NAME", help="registered estimator (see --list)")
    p.add_argument("--input", "-i", action="append", metavar="FILE[:ARRAY]",
                   help="a record (.csv, .npz, .mat); repeat for several records of one condition")
    p.add_argument("--output", "-o", metavar="OUT.csv",
                   help="parameters over time; the IRF/FRF goes to OUT_irf.csv / OUT_frf.csv")
    p.add_argument("--set", action="append", metavar="KEY=VALUE", dest="settings", default=[],
                   help="estimator setting, repeatable; units allowed (lag_before=40ms)")
    p.add_argument("--decimate", type=int, default=1, metavar="Q",
                   help="decimate every record by the whole factor Q (anti-alias filtered)")
    p.add_argument("--array", metavar="NAME", help="N x 2 [angle, torque] array in NPZ/.mat inputs")
    p.add_argument("--fs", type=float, metavar="HZ", help="sampling rate when the file has none")
    p.add_argument("--torque-sign", type=int, choices=(1, -1), default=1, metavar="{1,-1}",
                   help="-1 negates every torque record (for recordings whose torque is positive "
                        "opposite to the angle, e.g. the REKLAB ankle data)")
    p.add_argument("--ensemble", action="store_true",
                   help="take the --input records as realizations of one time-varying condition (an ensemble); "
                        "a file with 2-D angle and torque always is one")
    p.add_argument("--plot", metavar="FIG.png", help="also draw the estimate (.png, .pdf or .svg)")
    p.add_argument("--list", action="store_true",
                   help="list the estimators (and with --estimator its settings) and exit")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Execute ``estimate``; returns 0 or raises :class:`~jointbench.errors.JointBenchError`."""
    import estimators

    if args.list:
        print(list_text(args.estimator))
        return 0
    missing = [opt for opt, v in (("--estimator", args.estimator), ("--input", args.input),
                                  ("--output", args.output)) if not v]
    if missing:
        raise ConfigError(f"estimate: missing {', '.join(missing)} (see jointbench estimate --help)")
    if args.decimate < 1:
        raise ConfigError(f"--decimate: must be a whole number >= 1, got {args.decimate}")
    if args.fs is not None and not (np.isfinite(args.fs) and args.fs > 0):
        raise ConfigError(f"--fs: must be > 0 Hz, got {args.fs}")
    estimator = estimators.make(args.estimator, parse_assignments(args.settings, where="--set"),
                                where="--set")
    sources = [io.parse_source(s, args.array) for s in args.input]
    out = Path(args.output)
    plot = Path(args.plot) if args.plot else None
    _check_outputs(out, plot, sources)

    ensemble = args.ensemble or (len(sources) > 1 and "ensemble" in estimator.accepts
                                 and not {"trial", "pooled"} & estimator.accepts)
    records = io_ensemble.read_records(sources, fs=args.fs, ensemble=ensemble)
    raw = list(records)                     # the trials, or the realizations of an ensemble
    if args.torque_sign == -1:
        raw = [t.replace(torque=-t.torque) for t in raw]
    trials = [decimate_trial(t, args.decimate) for t in raw]
    est = estimator.fit(Ensemble(tuple(trials), name=records.name) if isinstance(records, Ensemble) else trials)

    frame = est.to_frame()
    response = est.response_frame()
    written = [(out, len(frame), list(frame.columns))]
    atomic_write(out, lambda p: frame.to_csv(p, index=False))
    if response is not None:
        side = response_path(out, est)
        atomic_write(side, lambda p: response.to_csv(p, index=False))
        written.append((side, len(response), list(response.columns)))
    if plot is not None:
        from benchmarks.plots_estimate import plot_estimate

        atomic_write(plot, lambda p: plot_estimate(est, p, trials=trials, fmt=plot.suffix[1:].lower()))
        written.append((plot, None, None))
    print(summary_text(args.estimator, estimator.settings, raw, trials, est, written,
                       torque_sign=args.torque_sign))
    return 0


# --- pieces (public so that tests and other commands can use them) --------------------------------

def decimate_trial(trial: Trial, q: int) -> Trial:
    """Decimate ``trial`` by the whole factor ``q`` with :func:`jointbench.signal.resample_trial`."""
    try:
        return resample_trial(trial, trial.fs / q)
    except InputError as exc:
        raise InputError(f"--decimate {q}: {exc}") from None


def prediction_vaf(est: Estimate, trial: Trial) -> float:
    """VAF (%) of the torque predicted from the angle, on one record.

    Both signals have their means removed: ``vaf(torque - mean(torque),
    est.predict(angle - mean(angle)))``, over the whole record (edge samples included). ``nan`` when
    the estimate cannot predict this record or the torque is constant.
    """
    y = trial.output - np.mean(trial.output)
    u = trial.input - np.mean(trial.input)
    try:
        yhat = np.asarray(est.predict(u), float)
        return vaf(y, yhat)
    except (NotImplementedError, ValueError):
        return float("nan")


def response_kind(est: Estimate) -> str | None:
    """``"irf"``, ``"frf"`` or ``None``: the kind of :meth:`Estimate.response_frame`.

    For a :class:`ParametricEstimate` the kind of its ``basis``; otherwise the estimate's type, and
    for other types the frame's columns (``lag`` or ``freq_hz``).
    """
    base = est.basis if isinstance(est, ParametricEstimate) else est
    if isinstance(base, IRFEstimate):
        return "irf"
    if isinstance(base, FRFEstimate):
        return "frf"
    frame = est.response_frame()
    if frame is None:
        return None
    if "lag" in frame.columns:
        return "irf"
    if "freq_hz" in frame.columns:
        return "frf"
    return "response"


def response_path(out: Path, est: Estimate) -> Path:
    """``OUT_irf.csv`` or ``OUT_frf.csv`` beside ``OUT.csv``."""
    return out.with_name(f"{out.stem}_{response_kind(est)}{out.suffix}")


def list_text(name: str | None = None) -> str:
    """Registered estimators, and the settings table of ``name`` when given."""
    import estimators

    names = estimators.REGISTRY.names()
    lines = ["estimators:"]
    width = max((len(n) for n in names), default=0)
    for n in names:
        doc = (estimators.REGISTRY.get(n).__doc__ or "").strip().splitlines()
        lines.append(f"  {n:<{width}}  {doc[0] if doc else ''}".rstrip())
    if not names:
        lines.append("  (none registered)")
    if name:
        cls = estimators.REGISTRY.get(name)
        rows = describe(cls.Settings)
        lines += ["", f"settings of {name!r} (--set KEY=VALUE):"]
        if not rows:
            lines.append("  (none)")
        head = ("key", "type [unit]", "default", "meaning")
        w = [max(len(r[i]) for r in [head, *rows]) for i in range(3)]
        for r in [head, *rows] if rows else []:
            lines.append(f"  {r[0]:<{w[0]}}  {r[1]:<{w[1]}}  {r[2]:<{w[2]}}  {r[3]}".rstrip())
    return "\n".join(lines)


def summary_text(name: str, settings, raw: Sequence[Trial], trials: Sequence[Trial], est: Estimate,
                 written: Sequence[tuple[Path, int | None, list[str] | None]],
                 torque_sign: int = 1) -> str:
    """The text printed after a successful run."""
    lines = [f"estimator: {name} ({_settings_text(settings)})",
             "inputs:" + (" (torque negated)" if torque_sign == -1 else "")]
    w = max(len(t.name) for t in raw)
    for r, t in zip(raw, trials):
        line = f"  {r.name:<{w}}  {r.n} samples at {r.fs:g} Hz ({r.duration:.3f} s)"
        if t is not r:
            line += f", decimated to {t.n} samples at {t.fs:g} Hz"
        lines.append(line)
    lines.append("estimate: " + parameters_text(est))
    extra = {k: v for k, v in est.summary().items()
             if k not in ("estimator", "fs_hz", "I", "B", "K", "stiffness")}
    for k, v in extra.items():
        lines.append(f"  {k}: {v:.6g}" if isinstance(v, float) else f"  {k}: {v}")
    lines.append("VAF of predicted torque (means removed):")
    for t in trials:
        lines.append(f"  {t.name:<{w}}  {prediction_vaf(est, t):6.1f} %")
    lines.append("wrote:")
    for path, rows, cols in written:
        lines.append(f"  {path}" + (f"  ({rows} rows: {', '.join(cols)})" if cols else ""))
    return "\n".join(lines)


def parameters_text(est: Estimate) -> str:
    """``I = ..., B = ..., K = ...`` with units (mean and range when time-varying), or the stiffness."""
    params = est.parameters()
    if not params:
        params = {"stiffness": np.atleast_1d(est.stiffness(est.time))}
    parts = []
    for k, v in params.items():
        v = np.asarray(v, float)
        text = f"{k} = {np.mean(v):.4g} {UNITS.get(k, '')}".rstrip()
        if np.ptp(v) > 1e-9 * max(abs(np.mean(v)), 1e-300):
            text += f" (mean; {np.min(v):.4g} to {np.max(v):.4g})"
        parts.append(text)
    return ", ".join(parts)


def _settings_text(settings) -> str:
    if not dataclasses.is_dataclass(settings):
        return "no settings"
    items = [f"{f.name}={getattr(settings, f.name)!r}" for f in dataclasses.fields(settings)]
    return ", ".join(items) if items else "no settings"


def _check_outputs(out: Path, plot: Path | None, sources: Sequence[io.Source]) -> None:
    if out.suffix.lower() != ".csv":
        raise ConfigError(f"--output: must name a .csv file, got {str(out)!r}")
    if out.is_dir():
        raise ConfigError(f"--output: {out} is a folder; give a file name such as {out / 'estimate.csv'}")
    if plot is not None and plot.suffix.lower() not in PLOT_SUFFIXES:
        raise ConfigError(f"--plot: must end in {', '.join(PLOT_SUFFIXES)}, got {str(plot)!r}")
    targets = [out, out.with_name(f"{out.stem}_irf{out.suffix}"),
               out.with_name(f"{out.stem}_frf{out.suffix}")] + ([plot] if plot else [])
    inputs = {os.path.abspath(s.path) for s in sources}
    for t in targets:
        if os.path.abspath(t) in inputs:
            raise ConfigError(f"refusing to overwrite input file {t}")
