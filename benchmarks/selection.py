"""Selecting tidy rows by a check's conditions (``select``, ``versus``, ``domain`` of the published-values
file): :class:`Selection`, what :func:`benchmarks.checks.judge` scores every check with."""
from __future__ import annotations

from typing import Mapping

import numpy as np
import pandas as pd


class Selection:
    """The tidy rows prepared for many selections (the checks of :func:`benchmarks.checks.judge`): each
    column's values, text and numbers are taken out of the frame once, as numpy arrays, and a selection
    narrows a set of row positions with them; only the columns a caller asks for are cut out of the frame.

    Row by row the same conditions as comparing the frame's columns each time (``==`` on the values of
    ``part``, ``status`` and ``metric``; text for other values, numbers for numbers and ranges): the
    conditions look at one row at a time, so computing them once for every row and then picking positions
    is the same as computing them for the rows picked (issue 22: the ~600 selections of a run of
    vanderuit2018_table1 cut its 25 columns each time, 1.5 CPU-s).
    """

    def __init__(self, rows: pd.DataFrame):
        self.rows = rows
        self._arrays: dict = {}
        self._parts: dict = {}
        self._frames: dict = {}

    def _array(self, kind: str, column: str) -> np.ndarray:
        got = self._arrays.get((kind, column))
        if got is None:
            col = self.rows[column]
            if kind == "values":
                got = col.to_numpy()
            elif kind == "floats":
                got = col.to_numpy(float)
            elif kind == "text":
                got = col.astype(str).to_numpy()
            else:                                         # numbers: NaN where a value is not one
                got = pd.to_numeric(col, errors="coerce").astype(float).to_numpy()
            self._arrays[(kind, column)] = got
        return got

    def _match(self, column: str, value, pos: np.ndarray) -> np.ndarray:
        if isinstance(value, Mapping):       # a range: {lt|le|gt|ge: bound}
            num = self._array("numbers", column)[pos]
            ok = ~np.isnan(num)
            for op, bound in value.items():
                ok &= {"lt": num < bound, "le": num <= bound, "gt": num > bound, "ge": num >= bound}[op]
            return ok
        if isinstance(value, (int, float)) and not isinstance(value, bool):
            return np.isclose(self._array("numbers", column)[pos], float(value), rtol=1e-9, atol=0)
        return np.asarray(self._array("text", column)[pos] == str(value), dtype=bool)

    def positions(self, part: str, where: Mapping, within: np.ndarray | None = None) -> np.ndarray:
        """Positions of the rows of ``part`` (successful cases) matching ``where`` (among ``within``, positions
        of such rows, when given), in the frame's order."""
        pos = self._parts.get(part) if within is None else within
        if pos is None:
            pos = self._parts[part] = np.flatnonzero((self._array("values", "part") == part)
                                                     & (self._array("values", "status") == "ok"))
        columns = self.rows.columns
        metric = where.get("metric")
        if isinstance(metric, str) and "metric" in columns:    # the most selective first
            pos = pos[self._array("values", "metric")[pos] == metric]
        for k, v in where.items():
            if k not in columns:
                return pos[:0]
            if k == "metric" and isinstance(v, str):
                continue
            pos = pos[self._match(k, v, pos)]
        return pos

    def frame(self, pos: np.ndarray, *columns: str) -> pd.DataFrame:
        """The rows at ``pos``, with ``value`` and those of ``columns`` that exist."""
        cols = tuple(dict.fromkeys(c for c in ("value", *columns) if c in self.rows.columns))
        narrow = self._frames.get(cols)
        if narrow is None:
            narrow = self._frames[cols] = self.rows[list(cols)]
        return narrow.iloc[pos]

    def values(self, pos: np.ndarray) -> np.ndarray:
        """``value`` of the rows at ``pos``, as floats."""
        return self._array("floats", "value")[pos]


def select(rows: pd.DataFrame, part: str, where: Mapping) -> pd.DataFrame:
    """Rows of ``part`` (successful cases) whose columns equal ``where`` (or lie in its ranges): see
    :class:`Selection` (for many selections of one frame, use one)."""
    return rows.iloc[Selection(rows).positions(part, where)]
