"""Tidy tables from case results, and the comparison with published values."""
from __future__ import annotations

import numpy as np
import pandas as pd

from benchmarks.config import Check

ROW_FRONT = ["study", "part", "case_id", "seed", "estimator", "metric", "value", "status", "error",
             "wall_time_s", "git_commit"]


def cases_frame(results, commit: str) -> pd.DataFrame:
    """One row per metric per case (a failed case gives one row with its error)."""
    recs = []
    for r in results:
        base = {"study": r.case.study, "part": r.case.part, "case_id": r.case.case_id, "seed": r.case.seed,
                **{k: v for k, v in r.case.sweep.items()}, "status": r.status, "error": r.error,
                "wall_time_s": round(r.wall_time_s, 4), "git_commit": commit,
                "backend": getattr(r.case, "backend", "analytic"),
                "sim_time_s": round(sum(t for _, t in r.sim_times), 6), "n_trials": len(r.sim_times)}
        if r.status != "ok" or not r.rows:
            recs.append({**base, "estimator": "", "metric": "", "value": np.nan})
        for row in r.rows:
            recs.append({**base, **row})
    df = pd.DataFrame.from_records(recs)
    front = [c for c in ROW_FRONT if c in df.columns]
    return df[front + sorted(c for c in df.columns if c not in front)]


def curves_frame(results) -> pd.DataFrame:
    """Curves in long form: one row per point."""
    frames = []
    for r in results:
        for c in r.curves:
            labels = {k: v for k, v in c.items() if k not in ("x", "y")}
            f = pd.DataFrame({"x": c["x"], "y": c["y"]})
            for k, v in {"part": r.case.part, "case_id": r.case.case_id, "seed": r.case.seed,
                         **r.case.sweep, **labels}.items():
                f[k] = v
            frames.append(f)
    if not frames:
        return pd.DataFrame(columns=["part", "case_id", "seed", "curve", "series", "x", "y"])
    return pd.concat(frames, ignore_index=True)


def _match(col: pd.Series, value) -> pd.Series:
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        num = pd.to_numeric(col, errors="coerce")
        return pd.Series(np.isclose(num.astype(float), float(value), rtol=1e-9, atol=0), index=col.index)
    return col.astype(str) == str(value)


def select(rows: pd.DataFrame, part: str, where: dict) -> pd.DataFrame:
    """Rows of ``part`` (successful cases) whose columns equal ``where``."""
    sel = rows[(rows["part"] == part) & (rows["status"] == "ok")]
    for k, v in where.items():
        if k not in sel.columns:
            return sel.iloc[0:0]
        sel = sel[_match(sel[k], v)]
    return sel


def _grouped(sel: pd.DataFrame, column: str, aggregate: str) -> pd.Series:
    """Aggregate of the finite values per value of ``column`` (numeric order when numeric)."""
    sel = sel[np.isfinite(sel["value"].to_numpy(float))]
    if not column:
        return pd.Series({"": getattr(np, aggregate)(sel["value"].to_numpy(float))}) if len(sel) else pd.Series()
    if column not in sel.columns:
        return pd.Series(dtype=float)
    g = sel.groupby(sel[column].astype(str), sort=False)["value"].agg(lambda v: getattr(np, aggregate)(v.to_numpy(float)))
    num = pd.to_numeric(pd.Series(g.index, index=g.index), errors="coerce")
    order = num.sort_values().index if num.notna().all() else sorted(g.index)
    return g.loc[list(order)]


def _trend(c: Check, rows: pd.DataFrame) -> tuple[float, str, int]:
    """Largest move against ``c.direction`` between consecutive aggregates over ``c.over``."""
    sel = select(rows, c.part, c.select)
    m = _grouped(sel, c.over, c.aggregate)
    if len(m) < 2:
        return np.nan, "", len(sel)
    d = np.diff(m.to_numpy(float))
    against = d if c.direction == "decreasing" else -d
    spread = ", ".join(f"{k}: {v:.4g}" for k, v in m.items())
    return float(np.max(against)), f"{c.over} -> {spread}", len(sel)


def _difference(c: Check, rows: pd.DataFrame) -> tuple[float, str, int]:
    """aggregate(select) - aggregate(versus) per value of ``c.by``; the group closest to (or furthest
    beyond) a bound is the reproduced value."""
    a, b = select(rows, c.part, c.select), select(rows, c.part, c.versus or {})
    ma, mb = _grouped(a, c.by, c.aggregate), _grouped(b, c.by, c.aggregate)
    keys = [k for k in ma.index if k in mb.index]
    if not keys:
        return np.nan, "", len(a) + len(b)
    d = pd.Series({k: float(ma[k] - mb[k]) for k in keys})
    margin = np.minimum(d - c.low, c.high - d)
    worst = margin.idxmin()
    spread = ", ".join(f"{k}: {v:+.4g}" for k, v in d.items()) if c.by else ""
    return float(d[worst]), (f"{c.by} -> {spread}" if c.by else spread), len(a) + len(b)


def compare(checks: tuple[Check, ...], rows: pd.DataFrame, parts_run: set[str]) -> pd.DataFrame:
    """One row per check: published, reproduced, tolerance, pass/miss.

    Check kinds: ``value`` (aggregate over seeds of the selected rows within [low, high]); ``trend``
    (aggregates per value of ``over`` must move in ``direction``; reproduced = the largest move against
    it, which must not exceed ``slack``); ``difference`` (aggregate of ``select`` minus that of ``versus``
    per value of ``by``, every one within [low, high]; reproduced = the one closest to or beyond a bound).
    """
    out = []
    for c in checks:
        if c.part not in parts_run:
            continue
        if c.kind == "value":
            sel = select(rows, c.part, c.select)
            v = sel["value"].to_numpy(float)
            v = v[np.isfinite(v)]
            n = len(v)
            rep = float(getattr(np, c.aggregate)(v)) if n else np.nan
            spread = f"{v.min():.4g} to {v.max():.4g}" if n > 1 else ""
            low, high = c.low, c.high
        else:
            rep, spread, n = _trend(c, rows) if c.kind == "trend" else _difference(c, rows)
            low, high = (-np.inf, c.slack) if c.kind == "trend" else (c.low, c.high)
        if not np.isfinite(rep):
            status = "miss"
            note = "no result: the case failed or produced no such metric (see the failed cases)"
        else:
            status = "pass" if low <= rep <= high else "miss"
            note = "" if status == "pass" else c.if_missed
        out.append({"check": c.id, "description": c.description, "published": c.published,
                    "reproduced": rep, "low": low, "high": high, "status": status,
                    "aggregate": c.aggregate if c.kind == "value" else f"{c.kind} of {c.aggregate}s",
                    "n": n, "spread": spread, "part": c.part,
                    "source": c.source, "note": note})
    return pd.DataFrame(out, columns=["check", "description", "published", "reproduced", "low", "high",
                                      "status", "aggregate", "n", "spread", "part", "source", "note"])


def summarize(rows: pd.DataFrame, part: str, by: list[str]) -> pd.DataFrame:
    """Median and min-max over seeds of every metric of a part, grouped by ``by`` columns."""
    sel = rows[(rows["part"] == part) & (rows["status"] == "ok")]
    by = [b for b in by if b in sel.columns]
    keys = by + ["estimator", "metric"]
    g = sel.groupby(keys, dropna=False, sort=False)["value"]
    return g.agg(median="median", min="min", max="max", n="count").reset_index()


def markdown(df: pd.DataFrame, floatfmt: str = ".4g") -> str:
    """A GitHub markdown table (no extra dependency)."""
    if df.empty:
        return "_(no rows)_\n"

    def fmt(v):
        if isinstance(v, float):
            return "" if np.isnan(v) else format(v, floatfmt)
        return str(v).replace("|", "\\|").replace("\n", " ")

    head = "| " + " | ".join(map(str, df.columns)) + " |"
    sep = "|" + "|".join("---" for _ in df.columns) + "|"
    body = ["| " + " | ".join(fmt(v) for v in row) + " |" for row in df.itertuples(index=False)]
    return "\n".join([head, sep, *body]) + "\n"
