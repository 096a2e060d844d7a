"""The ``jointbench estimate`` subcommand: identify joint impedance from recorded angle and torque.

::

    jointbench estimate --estimator NAME --input FILE [--input FILE ...] --output OUT.csv
                        [--set key=value ...] [--decimate Q] [--decimate-filter {fir,chebyshev}]
                        [--window START:END] [--array NAME]
                        [--fs HZ] [--torque-sign {1,-1}] [--plot FIG.png] [--list]

Parses its arguments and calls :func:`jointbench.api.fit` (the checked pipeline,
:mod:`jointbench.fitting.pipeline`, makes every decision: reading the records, the ensemble, the schedule,
torque sign, decimation, crop, checks, fit, scores), its errors worded with this command's flags; only then,
when every step that can fail has passed, it
writes ``OUT.csv`` (:meth:`~jointbench.core.estimate.Estimate.to_frame`), ``OUT_irf.csv`` or
``OUT_frf.csv`` (the response, when the estimate has one), ``OUT_prediction.csv`` (what each VAF is
computed on) and the figure, and prints a summary. User errors raise
:class:`~jointbench.core.errors.JointBenchError`; the top-level CLI prints them on one line and exits with
status 2. See ``docs/estimate.md``.

Heavy modules (numpy's friends, the estimators, matplotlib) are imported inside the functions that need
them, so that ``--list`` and ``--help`` start quickly.
"""
from __future__ import annotations

import argparse
import dataclasses
import os
import re
from pathlib import Path
from typing import TYPE_CHECKING, Sequence

from jointbench.core.errors import ConfigError, worded_as
from jointbench.core.files import atomic_write_set

if TYPE_CHECKING:  # pragma: no cover
    import numpy as np

    from jointbench.fitting.pipeline import Fit

PLOT_SUFFIXES = (".png", ".pdf", ".svg")
UNITS = {"I": "kg m^2", "B": "N m s/rad", "K": "N m/rad", "stiffness": "N m/rad"}

_EPILOG = """\
inputs: CSV with a header naming columns time, angle, torque (s, rad, N m; other columns ignored);
NPZ or MATLAB .mat (v4-v7.3) with variables time, angle, torque; or an N x 2 [angle, torque] array of
an NPZ/.mat file chosen by --array NAME or FILE:NAME, sampled at the file's scalar 'fs' or --fs;
or a REKLAB nldat object of a .mat file by FILE:NAME (channels by name, the rate from domainIncr).
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
                   help="parameters over time; the IRF/FRF goes to OUT_irf.csv / OUT_frf.csv, the "
                        "torque and its prediction to OUT_prediction.csv")
    p.add_argument("--set", action="append", metavar="KEY=VALUE", dest="settings", default=[],
                   help="estimator setting, repeatable; units allowed (lag_before=40ms); auto=true "
                        "chooses a time-varying method's smoothing from the data")
    p.add_argument("--decimate", type=int, default=1, metavar="Q",
                   help="decimate every record by the whole factor Q (anti-alias filtered)")
    p.add_argument("--decimate-filter", default="fir", metavar="{fir,chebyshev}",
                   help="the anti-alias filter of --decimate: fir (default), or chebyshev: the Chebyshev IIR of "
                        "MATLAB's and Octave's decimate, as the REKLAB toolbox's analyses use")
    p.add_argument("--window", metavar="START:END",
                   help="keep only this part of every record, in seconds from its first sample "
                        "(e.g. 5s:45s, 500ms:, :30)")
    p.add_argument("--array", metavar="NAME", help="N x 2 [angle, torque] array in NPZ/.mat inputs")
    p.add_argument("--fs", metavar="HZ", help="sampling rate when the file has none (1000, 1 kHz)")
    p.add_argument("--torque-sign", type=int, choices=(1, -1), default=1, metavar="{1,-1}",
                   help="-1 negates every torque record (for recordings whose torque is positive "
                        "opposite to the angle, e.g. the REKLAB ankle data)")
    p.add_argument("--ensemble", action="store_true",
                   help="take the --input records as realizations of one time-varying condition (an ensemble); "
                        "a file with 2-D angle and torque always is one")
    p.add_argument("--plot", metavar="FIG.png", help="also draw the estimate (.png, .pdf or .svg)")
    p.add_argument("--list", action="store_true",
                   help="list the estimators (and with --estimator its settings) and exit")
    p.add_argument("--plugin", action="append", metavar="MODULE",
                   help="import an outside estimator first: a module name or the path of a .py file; repeatable "
                        "(installed plugins with a 'jointbench.estimators' entry point need none)")
    p.add_argument("--schedule", metavar="NAME",
                   help="scheduling variable of a parameter-varying estimator (pv_irf, pv_parallel_cascade): "
                        "angle_slow (the angle low-passed), angle, or a column (CSV) / array (NPZ, .mat) of the "
                        "input; prints K at chosen values with intervals (and the reflex gain, when fitted)")
    p.add_argument("--at", metavar="V1,V2,...",
                   help="with --schedule: the scheduling values to print K at (default: 5 over the range visited), "
                        "e.g. --at -0.4,0,0.2")
    p.set_defaults(func=run)


#: how this command words the arguments of :func:`jointbench.api.fit` in its messages
FLAGS = {"data": "--input", "estimator": "--estimator", "settings": "--set", "decimate": "--decimate",
         "decimate_filter": "--decimate-filter",
         "window": "--window", "array": "--array", "fs": "--fs", "torque_sign": "--torque-sign",
         "ensemble": "--ensemble", "schedule": "--schedule"}


def run(args: argparse.Namespace) -> int:
    """Execute ``estimate``: parse the arguments, fit with :func:`jointbench.api.fit` (every decision is made
    there), then write the outputs as one set and print the summary. Returns 0 or raises
    :class:`~jointbench.core.errors.JointBenchError`."""
    if getattr(args, "plugin", None):
        from jointbench.core import plugins

        for ref in args.plugin:
            plugins.load(ref, "--plugin")
    if args.list:
        print(list_text(args.estimator))
        return 0
    missing = [opt for opt, v in (("--estimator", args.estimator), ("--input", args.input),
                                  ("--output", args.output)) if not v]
    if missing:
        raise ConfigError(f"estimate: missing {', '.join(missing)} (see jointbench estimate --help)")
    at = parse_at(args.at) if args.at else None
    if at is not None and not args.schedule:
        raise ConfigError("--at: needs --schedule (the scheduling variable the values belong to)")
    out = Path(args.output)
    plot = Path(args.plot) if args.plot else None
    _check_outputs(out, plot, args.input)
    from jointbench import api
    from jointbench.core.schema import parse_assignments

    with worded_as(FLAGS):
        fit = api.fit(args.estimator, list(args.input), fs=args.fs, array=args.array,
                      settings=parse_assignments(args.settings, where="--set"), decimate=args.decimate,
                      window=args.window, torque_sign=args.torque_sign, ensemble=True if args.ensemble else None,
                      schedule=args.schedule, decimate_filter=args.decimate_filter)
        figure = fit.plot(fmt=plot.suffix[1:].lower()) if plot is not None else None
    written = write_outputs(out, plot, fit, figure)
    print(summary_text(args.estimator, fit.estimator.settings, fit, written, torque_sign=args.torque_sign))
    if args.schedule:
        print(stiffness_text(fit.estimate, at))
    return 0


# --- presentation: the values of --at, the summary, the output files -----------------------------------

#: options whose value may start with a minus sign (argparse takes ``--at -0.4,0`` for an option ``-0.4,0``: its
#: own test for a negative number knows no lists, so only ``--at=-0.4,0`` passed)
SIGNED_VALUE_OPTIONS = ("--at",)
_SIGNED = re.compile(r"-\.?\d[\d.eE+\-,\s]*")


def joined_signed_values(argv: Sequence[str]) -> list[str]:
    """``argv`` with each of :data:`SIGNED_VALUE_OPTIONS` followed by a value that starts with a minus sign and
    reads as numbers (``-0.4,0``) written as one argument (``--at=-0.4,0``), which argparse takes as the value;
    anything else unchanged (``--at --schedule ...`` still lacks its value, and says so)."""
    argv = [str(a) for a in argv]
    out, i = [], 0
    while i < len(argv):
        if argv[i] in SIGNED_VALUE_OPTIONS and i + 1 < len(argv) and _SIGNED.fullmatch(argv[i + 1]):
            out.append(f"{argv[i]}={argv[i + 1]}")
            i += 2
        else:
            out.append(argv[i])
            i += 1
    return out

def parse_at(text: str) -> "np.ndarray":
    """``V1,V2,...`` -> an array of numbers (one-line error otherwise)."""
    import numpy as np

    try:
        values = np.array([float(v) for v in str(text).split(",") if v.strip()])
    except ValueError:
        raise ConfigError(f"--at: expected numbers separated by commas, e.g. -0.3,0,0.2; got {text!r}") from None
    if not values.size or not np.all(np.isfinite(values)):
        raise ConfigError(f"--at: expected finite numbers separated by commas, got {text!r}")
    return values




def stiffness_text(est, at: "np.ndarray | None" = None) -> str:
    """K at the scheduling values ``at`` (default: 5 over the visited range) with the estimate's band, and the
    reflex pathway's static gain there when the estimate has one (``pv_parallel_cascade``)."""
    import numpy as np

    from jointbench.core.intervals import LEVEL

    if not hasattr(est, "stiffness_at"):
        return ""
    values = np.linspace(est.lo, est.hi, 5) if at is None else np.asarray(at, float)
    k = est.stiffness_at(values)
    lo, hi = est.stiffness_band(values)
    level = getattr(est, "level", LEVEL)
    lines = [f"K at chosen values of the scheduling variable '{est.schedule_name}' (visited {est.lo:.4g} ... "
             f"{est.hi:.4g}; {100 * level:g} % pointwise intervals in [ ]):"]
    gains = (est.reflex_gain_at(values) if getattr(est, "reflex_h", None) is not None
             and hasattr(est, "reflex_gain_at") else [None] * len(values))
    for v, kk, a, b, g in zip(values, k, lo, hi, gains):
        outside = "" if est.lo <= v <= est.hi else "  (outside the visited range: extrapolated)"
        reflex = "" if g is None else f", reflex gain {g:.4g} N.m.s/rad"
        lines.append(f"  {v:10.4g}   K = {kk:.4g} [{a:.4g}, {b:.4g}] N.m/rad{reflex}{outside}")
    return "\n".join(lines)


def response_kind(est) -> str | None:
    """``"irf"``, ``"frf"`` or ``None``: the kind of :meth:`Estimate.response_frame`.

    For a :class:`ParametricEstimate` the kind of its ``basis``; otherwise the estimate's type, and
    for other types the frame's columns (``lag`` or ``freq_hz``).
    """
    from jointbench.core.estimate import FRFEstimate, IRFEstimate, ParametricEstimate

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


def response_path(out: Path, est) -> Path:
    """``OUT_irf.csv`` or ``OUT_frf.csv`` beside ``OUT.csv``."""
    return out.with_name(f"{out.stem}_{response_kind(est)}{out.suffix}")


def prediction_path(out: Path) -> Path:
    """``OUT_prediction.csv`` beside ``OUT.csv``."""
    return out.with_name(f"{out.stem}_prediction{out.suffix}")


def prediction_frame(trials: list, predictions: list):
    """Long table: ``record, time, torque, predicted_torque, in_vaf`` (the torque as the VAF compares it)."""
    import numpy as np
    import pandas as pd

    parts = [pd.DataFrame({"record": t.name, "time": t.time, "torque": p.y, "predicted_torque": p.yhat,
                           "in_vaf": p.used}) for t, p in zip(trials, predictions)]
    frame = pd.concat(parts, ignore_index=True)
    frame["in_vaf"] = frame["in_vaf"].astype(np.int8)
    return frame


def write_outputs(out: Path, plot: Path | None, o: Fit, figure: bytes | None = None
                  ) -> list[tuple[Path, int | None, list[str] | None]]:
    """Write every output as one set (:func:`jointbench.core.files.atomic_write_set`): the fit and its figure
    are made before anything is written."""
    from jointbench.core.csv_text import write_csv      # pandas' bytes, faster (imports pandas: not for --list)

    written = [(out, len(o.frame), list(o.frame.columns))]
    tables = [(out, o.frame)]
    if o.response is not None:
        side = response_path(out, o.estimate)
        tables.append((side, o.response))
        written.append((side, len(o.response), list(o.response.columns)))
    pred = prediction_frame(o.trials, o.predictions)
    tables.append((prediction_path(out), pred))
    written.append((prediction_path(out), len(pred), list(pred.columns)))
    items = [(path, lambda p, table=table: write_csv(table, p)) for path, table in tables]
    if plot is not None and figure is not None:
        items.append((plot, lambda p: Path(p).write_bytes(figure)))
        written.append((plot, None, None))
    atomic_write_set(items)         # all or nothing: a full disk leaves the last good set as it was
    return written


def list_text(name: str | None = None) -> str:
    """Registered estimators, and the settings table of ``name`` when given."""
    from jointbench import estimators

    names = estimators.REGISTRY.names()
    lines = ["estimators:"]
    width = max((len(n) for n in names), default=0)
    for n in names:
        lines.append(f"  {n:<{width}}  {estimators.REGISTRY.summary(n)}".rstrip())
    if not names:
        lines.append("  (none registered)")
    if name:
        from jointbench.core.schema import describe

        cls = estimators.REGISTRY.get(name)
        rows = describe(cls.Settings)
        lines += ["", f"settings of {name!r} (--set KEY=VALUE):"]
        if not rows:
            lines.append("  (none)")
        head = ("key", "type [unit]", "default", "meaning")
        w = [max(len(r[i]) for r in [head, *rows]) for i in range(3)]
        for r in [head, *rows] if rows else []:
            lines.append(f"  {r[0]:<{w[0]}}  {r[1]:<{w[1]}}  {r[2]:<{w[2]}}  {r[3]}".rstrip())
        auto = getattr(cls, "AUTO", ())
        if auto:
            lines.append(f"  auto=true chooses {', '.join(auto)} from the data (or give a key the value auto)")
    return "\n".join(lines)


def summary_text(name: str, settings, o: Fit, written: Sequence[tuple[Path, int | None, list[str] | None]],
                 torque_sign: int = 1) -> str:
    """The text printed after a successful run."""
    est = o.estimate
    lines = [f"estimator: {name} ({_settings_text(settings)})",
             "inputs:" + (" (torque negated)" if torque_sign == -1 else "")]
    w = max(len(t.name) for t in o.raw)
    for r, t in zip(o.raw, o.trials):
        line = f"  {r.name:<{w}}  {r.n} samples at {r.fs:g} Hz ({r.duration:.3f} s)"
        if t.fs != r.fs:
            line += f", decimated to {t.fs:g} Hz"
        if t.time[0] != r.time[0] or abs(t.duration - r.duration) > 1.5 / t.fs:
            line += (f", fitted on {t.time[0] - r.time[0]:.3f} ... {t.time[-1] - r.time[0] + 1 / t.fs:.3f} s "
                     f"({t.n} samples)")
        elif t.fs != r.fs:
            line += f" ({t.n} samples)"
        lines.append(line)
    lines += [f"  {n}" for n in o.notes]
    lines.append("estimate: " + parameters_text(est))
    if est.intervals is not None:
        iv = est.intervals
        lines.append(f"  {100 * iv.level:g} % confidence intervals in [ ]: {iv.method}"
                     + ("; pointwise bands over time" if any(_varies(b[0]) for b in iv.bounds.values()) else ""))
    else:
        why = est.fit_info.get("intervals", "this estimator provides none")
        lines.append(f"  (no confidence intervals: {why.removeprefix('none: ')})")
    extra = {k: v for k, v in est.summary().items()
             if k not in ("estimator", "fs_hz", "I", "B", "K", "stiffness", "intervals")}
    for k, v in extra.items():
        lines.append(f"  {k}: {v:.6g}" if isinstance(v, float) else f"  {k}: {v}")
    defs = []
    for p in o.predictions:
        if p.definition not in defs:
            defs.append(p.definition)
    lines.append("VAF of the predicted torque, 100 (1 - var(y - yhat) / var(y)) in %, y and yhat: "
                 + "; ".join(defs))
    for t, vaf in zip(o.trials, o.vaf):
        lines.append(f"  {t.name:<{w}}  {vaf:6.1f} %")
    lines += [f"hint: {h}" for h in o.hints]
    lines.append("wrote:")
    for path, rows, cols in written:
        lines.append(f"  {path}" + (f"  ({rows} rows: {', '.join(cols)})" if cols else ""))
    return "\n".join(lines)


def _varies(v) -> bool:
    import numpy as np

    return np.ndim(v) > 0 and np.ptp(np.asarray(v, float)) > 0


def parameters_text(est) -> str:
    """``I = ... [lo, hi] unit, ...`` (mean and range when time-varying), or the stiffness."""
    import numpy as np

    params = est.parameters()
    if not params:
        params = {"stiffness": np.atleast_1d(est.stiffness(est.time))}
    bounds = est.intervals.bounds if est.intervals is not None else {}
    parts = []
    for k, v in params.items():
        v = np.asarray(v, float)
        unit = UNITS.get(k, "")
        varies = np.ptp(v) > 1e-9 * max(abs(np.mean(v)), 1e-300)
        text = f"{k} = {np.mean(v):.4g}"
        lo = hi = None
        if k in bounds:
            lo, hi = (np.broadcast_to(np.asarray(b, float), v.shape) for b in bounds[k])
        if not varies and lo is not None:
            text += f" [{np.min(lo):.4g}, {np.max(hi):.4g}]"
        text += f" {unit}".rstrip()
        if varies:
            text += f" (mean; {np.min(v):.4g} to {np.max(v):.4g}"
            if lo is not None:
                text += f"; pointwise band +- {np.median((hi - lo) / 2):.3g} (median half-width)"
            text += ")"
        parts.append(text)
    return ", ".join(parts)


def _settings_text(settings) -> str:
    if not dataclasses.is_dataclass(settings):
        return "no settings"
    items = [f"{f.name}={getattr(settings, f.name)!r}" for f in dataclasses.fields(settings)]
    return ", ".join(items) if items else "no settings"


def _check_outputs(out: Path, plot: Path | None, inputs: Sequence[str]) -> None:
    """Refuse outputs that cannot be written, or would overwrite an input (``FILE`` or ``FILE:ARRAY``), before
    anything is read or fitted."""
    if out.suffix.lower() != ".csv":
        raise ConfigError(f"--output: must name a .csv file, got {str(out)!r}")
    if out.is_dir():
        raise ConfigError(f"--output: {out} is a folder; give a file name such as {out / 'estimate.csv'}")
    if plot is not None and plot.suffix.lower() not in PLOT_SUFFIXES:
        raise ConfigError(f"--plot: must end in {', '.join(PLOT_SUFFIXES)}, got {str(plot)!r}")
    targets = [out, out.with_name(f"{out.stem}_irf{out.suffix}"), out.with_name(f"{out.stem}_frf{out.suffix}"),
               prediction_path(out)] + ([plot] if plot else [])
    from jointbench.fitting.read import parse_source       # the one reading of FILE[:ARRAY]

    given = {os.path.abspath(parse_source(s).path) for s in inputs}
    for t in targets:
        if os.path.abspath(t) in given:
            raise ConfigError(f"refusing to overwrite input file {t}")
        if t.is_dir():
            raise ConfigError(f"{t}: is a folder; cannot write the output there")
        parent = Path(os.path.abspath(t)).parent
        while not parent.exists() and parent != parent.parent:
            parent = parent.parent
        if not parent.is_dir() or not os.access(parent, os.W_OK | os.X_OK):
            raise ConfigError(f"{t}: cannot write there ({parent} is not a writable folder)")
