"""Selecting tidy rows by a check's conditions (``select``, ``versus``, ``domain`` of the published-values
file): :func:`select`, what :func:`benchmarks.checks.judge` scores every check with."""
from __future__ import annotations

from typing import Mapping

import numpy as np
import pandas as pd


def matches(column: pd.Series, value) -> pd.Series:
    """Which cells of ``column`` meet one condition of a check.

    ``value`` is a range (a mapping ``{lt|le|gt|ge: bound}``: numbers within every bound; a cell that is no
    number is outside), a number (cells equal to it within a relative 1e-9; text is no number), a list (cells
    meeting any one of its values: the variations or metrics one claim covers, issue 35) or anything else,
    compared as text (``str`` of the cell and of the value: ``True``, ``nan``, ``native``).
    """
    if isinstance(value, (list, tuple)):
        ok = pd.Series(False, index=column.index)
        for one in value:
            ok |= matches(column, one)
        return ok
    if isinstance(value, Mapping):
        num = pd.to_numeric(column, errors="coerce").astype(float)
        ok = num.notna()
        for op, bound in value.items():
            ok &= {"lt": num < bound, "le": num <= bound, "gt": num > bound, "ge": num >= bound}[op]
        return ok
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        num = pd.to_numeric(column, errors="coerce").astype(float)
        return pd.Series(np.isclose(num, float(value), rtol=1e-9, atol=0), index=column.index)
    return column.astype(str) == str(value)


def select(rows: pd.DataFrame, part: str, where: Mapping) -> pd.DataFrame:
    """The rows of ``part`` whose case succeeded (``status`` ``ok``) and that meet every condition of
    ``where`` (column -> :func:`matches`' value), in the frame's order; none when ``where`` names a column
    the rows lack."""
    sel = rows[(rows["part"] == part) & (rows["status"] == "ok")]
    for column, value in where.items():
        if column not in sel.columns:
            return rows.iloc[0:0]
        sel = sel[matches(sel[column], value)]
    return sel
