"""Tidy tables from case results: the rows (``cases.csv``), the curves behind the figures, and summaries over seeds.

The judging of those rows against the published values is :mod:`benchmarks.checks`.
"""
from __future__ import annotations


import numpy as np
import pandas as pd


ROW_FRONT = ["study", "part", "case_id", "seed", "estimator", "metric", "value", "status", "error",
             "wall_time_s", "git_commit", "plugin"]


def cases_frame(results, commit: str, plugins: dict[str, str] | None = None) -> pd.DataFrame:
    """One row per metric per case (a failed case gives one row with its error). ``plugins`` (estimator ->
    ``"<distribution>==<version> <source hash>"``, :func:`benchmarks.harness.fingerprint.plugin_hash`): every
    row of a case whose estimators include a plugin carries it in column ``plugin`` (several: joined by
    ``"; "``), the code that made its numbers beside ``git_commit``."""
    recs = []
    plugins = plugins or {}
    for r in results:
        code = "; ".join(plugins[e] for e in r.case.estimators if e in plugins)
        base = {"study": r.case.study, "part": r.case.part, "case_id": r.case.case_id, "seed": r.case.seed,
                **{k: v for k, v in r.case.sweep.items()}, "status": r.status, "error": r.error,
                "wall_time_s": round(r.wall_time_s, 4), "git_commit": commit, **({"plugin": code} if code else {}),
                "backend": getattr(r.case, "backend", "analytic"),
                "sim_time_s": round(sum(e[1] for e in r.sim_times), 6), "n_trials": len(r.sim_times),
                "n_responses": sum(1 for e in r.sim_times if not (len(e) > 2 and e[2]))}
        if r.status != "ok" or not r.rows:
            recs.append({**base, "estimator": "", "metric": "", "value": np.nan})
        for row in r.rows:
            recs.append({**base, **row})
    df = pd.DataFrame.from_records(recs)
    front = [c for c in ROW_FRONT if c in df.columns]
    return df[front + sorted(c for c in df.columns if c not in front)]


def curve_frame(result, curve: dict) -> pd.DataFrame:
    """One curve of a case result as rows, one per point: ``x``, ``y``, the case's part, id, seed and sweep
    values, then the curve's own labels (``curve``, ``series``, ...), each repeated over the points."""
    case = result.case
    labels = {k: v for k, v in curve.items() if k not in ("x", "y")}
    return pd.DataFrame({"x": curve["x"], "y": curve["y"], "part": case.part, "case_id": case.case_id,
                         "seed": case.seed, **case.sweep, **labels})


def curves_frame(results) -> pd.DataFrame:
    """Curves in long form: one row per point, the frames of every curve (:func:`curve_frame`) concatenated
    in the results' order (columns in order of appearance, a column a curve lacks empty there)."""
    frames = [curve_frame(r, c) for r in results for c in r.curves]
    if not frames:
        return pd.DataFrame(columns=["part", "case_id", "seed", "curve", "series", "x", "y"])
    return pd.concat(frames, ignore_index=True)


DIRTY_BANNER = "generated from an uncommitted tree - do not commit"


def stamp(commit: str) -> str:
    """The commit as recorded in the outputs: a dirty tree's stamp carries :data:`DIRTY_BANNER`."""
    return f"{commit} ({DIRTY_BANNER})" if commit.endswith("-dirty") else commit


def over_seeds(rows: pd.DataFrame, by: list[str], metrics: list[str] | None = None) -> pd.DataFrame:
    """Median, min, max and count of ``value`` over seeds, per combination of the ``by`` columns that
    exist (successful cases only; ``metrics`` keeps only those metrics). The one summary every table and
    figure of the reports uses; :func:`median_range` writes one of its rows as text."""
    sel = rows[rows["status"] == "ok"] if "status" in rows.columns else rows
    if metrics is not None:
        sel = sel[sel["metric"].isin(metrics)]
    by = [b for b in by if b in sel.columns]
    g = sel.groupby(by, dropna=False, sort=False)["value"]
    return g.agg(median="median", min="min", max="max", n="count").reset_index()


def median_range(median: float, low: float, high: float, n: int, digits: int | None = None) -> str:
    """'median (min to max)' over seeds: the median alone for one seed or no spread, empty for none;
    ``digits`` decimals, or four significant digits."""
    if median is None or not np.isfinite(median):
        return ""
    spec = f".{digits}f" if digits is not None else ".4g"
    if n <= 1 or low == high:
        return format(median, spec)
    return f"{median:{spec}} ({low:{spec}} to {high:{spec}})"


def summarize(rows: pd.DataFrame, part: str, by: list[str]) -> pd.DataFrame:
    """Median and min-max over seeds of every metric of a part, grouped by ``by`` columns."""
    return over_seeds(rows[rows["part"] == part], by + ["estimator", "metric"])
