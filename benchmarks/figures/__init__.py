"""Figure and table makers for the report, registered by name.

A study part names its maker with its ``figure`` key (default: the maker registered under the part's
protocol name), so one protocol can feed several figures (xu1998's parts all run ``xu1998.track``).
A maker is ``fn(part, rows, curves, folder, checks) -> PartReport``: it reads the tidy rows and curves
of one study part (never recomputes anything), may show the study's published values (``checks``, from
the published-values file: never copied into a maker) and writes PNG files into ``folder``.
"""
from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Callable

import pandas as pd

from jointbench.core.registry import Registry, package_modules, scan_modules


@dataclasses.dataclass
class PartReport:
    figures: list[tuple[str, str]] = dataclasses.field(default_factory=list)   # (file name, caption)
    tables: list[tuple[str, pd.DataFrame]] = dataclasses.field(default_factory=list)
    text: str = ""
    title: str = ""          # the part's heading in the report (default: its config description)


REGISTRY: Registry[Callable] = Registry("figure maker")


def register(name: str):
    """Register a figure maker under ``name`` (what a part's ``figure`` key names)."""
    return REGISTRY.register(name)


def new_figure(*args, **kw):
    """A matplotlib figure with the non-interactive backend (safe in worker processes and CI)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt.subplots(*args, **kw)


def save(fig, folder, name: str, dpi: int = 110) -> str:
    """``fig`` as the PNG ``folder / name`` at ``dpi``, cropped to what is drawn
    (:func:`jointbench.benchmarks.harness.png.tight_png`: one draw), and closed; returns ``name``."""
    import matplotlib.pyplot as plt

    from jointbench.benchmarks.harness.png import tight_png

    folder.mkdir(parents=True, exist_ok=True)
    try:
        (folder / name).write_bytes(tight_png(fig, dpi))
    finally:
        plt.close(fig)
    return name


def first_seed(curves: pd.DataFrame) -> pd.DataFrame:
    """The curves of the first seed (a figure shows one realization; the tables, every seed)."""
    return curves[curves["seed"] == curves["seed"].min()] if len(curves) else curves


def summary_over_seeds(rows: pd.DataFrame, part: str, by: list[str]) -> pd.DataFrame:
    """Each metric of ``part`` by ``by`` as one text cell, its median and range over seeds
    (:func:`benchmarks.tables.median_range`)."""
    from jointbench.benchmarks.tables import median_range, summarize

    s = summarize(rows, part, by)
    s["value"] = [median_range(m, lo, hi, n) for m, lo, hi, n in zip(s["median"], s["min"], s["max"], s["n"])]
    return s.drop(columns=["median", "min", "max"])


def _modules() -> list[tuple[str, Path]]:
    """Every figures module: this package's own (the generic one), the comparison grid's and each study's."""
    from jointbench.benchmarks import studies

    compare = ("jointbench.benchmarks.compare.figures", Path(__path__[0]).parent / "compare" / "figures.py")
    return [*package_modules(__name__, __path__), compare, *studies.modules("figures")]


# Names come from the modules' source; a maker's module is imported when a report first uses it.
REGISTRY.defer(scan_modules(_modules()))


def import_all() -> None:
    """Import every figures module (registering everything now rather than on first use)."""
    import importlib

    for module, _ in _modules():
        importlib.import_module(module)
