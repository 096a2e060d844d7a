"""Tidy tables from case results: the rows (``cases.csv``), the curves behind the figures, and summaries over seeds.

The judging of those rows against the published values is :mod:`benchmarks.checks`.
"""
from __future__ import annotations


import numpy as np
import pandas as pd


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
                "sim_time_s": round(sum(e[1] for e in r.sim_times), 6), "n_trials": len(r.sim_times),
                "n_responses": sum(1 for e in r.sim_times if not (len(e) > 2 and e[2]))}
        if r.status != "ok" or not r.rows:
            recs.append({**base, "estimator": "", "metric": "", "value": np.nan})
        for row in r.rows:
            recs.append({**base, **row})
    df = pd.DataFrame.from_records(recs)
    front = [c for c in ROW_FRONT if c in df.columns]
    return df[front + sorted(c for c in df.columns if c not in front)]


#: label types joined column by column: a list of them gets the dtype a broadcast one gets
_LABEL_TYPES = (str, float, int, bool)


def _kind(cols: dict) -> tuple | None:
    """What a curve's frame is made of (its column names, the kinds of ``x`` and ``y``, its labels' types),
    or None when it gets a frame of its own: ``x`` and ``y`` of one length, each a non-empty list of Python
    floats or a numeric 1-D array, the labels of :data:`_LABEL_TYPES` (integers within int64)."""
    points = []
    for v in (cols["x"], cols["y"]):
        if isinstance(v, list) and v and set(map(type, v)) == {float}:
            points.append("floats")
        elif isinstance(v, np.ndarray) and v.ndim == 1 and len(v) and v.dtype.kind in "fiub":
            points.append(v.dtype.str)
        else:
            return None
    if len(cols["x"]) != len(cols["y"]):
        return None
    types = tuple(type(v) for k, v in cols.items() if k not in ("x", "y"))
    if any(t not in _LABEL_TYPES for t in types) or any(
            type(v) is int and not -2 ** 63 <= v < 2 ** 63 for v in cols.values()):
        return None
    return tuple(cols), *points, types


def _joined(pieces: dict, counts: list[int]) -> pd.DataFrame:
    """One frame of curves of one :func:`_kind`: ``x`` and ``y`` concatenated, each label repeated over
    its curve's points."""
    out = {}
    for name, values in pieces.items():
        if name in ("x", "y"):
            out[name] = np.concatenate([np.asarray(v, dtype=float) if isinstance(v, list) else v for v in values])
        elif type(values[0]) is str:            # one type per column (the kind)
            out[name] = _repeated_text(values, counts)
        else:
            kind = type(values[0])
            out[name] = np.repeat(np.array(values, dtype={int: np.int64}.get(kind, kind)), counts)
    return pd.DataFrame(out)


def _repeated_text(values: list[str], counts: list[int]):
    """Each of ``values`` repeated ``counts`` times, as the column pandas makes of such a list: its
    Arrow-backed text is built by Arrow from the few distinct strings (pandas converted every one of the
    176 000 strings of a column of xu1998's curves, 13 ms a column), its other text as Python objects."""
    dtype = pd.Series(values[:1]).dtype
    if isinstance(dtype, pd.StringDtype) and dtype.storage == "pyarrow":
        import pyarrow as pa

        picks = pa.array(np.repeat(np.arange(len(values)), counts))
        return pd.array(pa.array(values, pa.large_string()).take(picks), dtype=dtype)
    return np.repeat(np.array(values, dtype=object), counts)


def curves_frame(results) -> pd.DataFrame:
    """Curves in long form: one row per point.

    The frame that concatenating one frame per curve gives (columns in order of appearance, a column a
    curve lacks empty there, dtypes by the same rules): the curves of one :func:`_kind` (a few kinds a
    study) are joined column by column into one frame each, those frames concatenated and the rows put
    back in the curves' order (a frame per curve, 633 of them in vanderuit2018_table1, cost 0.6 CPU-s;
    issue 22). A curve of no kind gets a frame of its own, as before."""
    groups: dict = {}       # kind -> [pieces: column -> values per curve, points per curve, rows]
    spans = []              # per curve, in order: (kind or own key, first row in that frame, rows)
    for r in results:
        fixed = {"part": r.case.part, "case_id": r.case.case_id, "seed": r.case.seed, **r.case.sweep}
        for c in r.curves:
            cols = {"x": c["x"], "y": c["y"], **fixed, **{k: v for k, v in c.items() if k not in ("x", "y")}}
            kind = _kind(cols)
            if kind is None:
                own = pd.DataFrame(cols)
                groups[key := object()] = own
                spans.append((key, 0, len(own)))
                continue
            g = groups.setdefault(kind, [{k: [] for k in cols}, [], 0])
            n = len(cols["x"])
            spans.append((kind, g[2], n))
            for k, v in cols.items():
                g[0][k].append(v)
            g[1].append(n)
            g[2] += n
    if not spans:
        return pd.DataFrame(columns=["part", "case_id", "seed", "curve", "series", "x", "y"])
    frames = [g if isinstance(g, pd.DataFrame) else _joined(g[0], g[1]) for g in groups.values()]
    start = dict(zip(groups, np.cumsum([0] + [len(f) for f in frames[:-1]])))
    out = pd.concat(frames, ignore_index=True) if len(frames) > 1 else frames[0]
    order = np.concatenate([np.arange(start[key] + first, start[key] + first + n) for key, first, n in spans])
    if not np.array_equal(order, np.arange(len(out))):
        out = out.take(order).reset_index(drop=True)
    return out


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
