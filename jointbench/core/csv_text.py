"""A table as CSV text, byte for byte what ``DataFrame.to_csv(index=False)`` writes, about four times faster.

Kept for ``jointbench estimate`` (issue 34 weighed every speed-only mechanism against the time a user
waits): ``jointbench estimate -e kbr`` on a one-minute record at 2.5 kHz (the gated wrist record of
tests/estimate_data.py, ``OUT_frf.csv`` 278 MB) waits 25.1 s with this writer and 37.6 s with
``DataFrame.to_csv`` (its CSV writes 4.8 against 17.9 CPU-s; medians of 3 interleaved runs on the 2-core
machine): half as long again. A study run's tables cost it little either way (the four paper studies'
warm runs: 0.81 CPU-s more with pandas, under 1 % of ``make reproduce``'s ~92); they go through it too,
so that every CSV output has one writer.

pandas turns every float into its text in numpy's formatter, one cell at a time. Arrow's cast of a float
column to text (:func:`pyarrow.compute.cast`) finds the same shortest round-trip digits in C++, but lays
some of them out differently (``3`` for ``3.0``, ``0.00001`` for ``1e-05``, ``1.5e-7`` for ``1.5e-07``,
``1.2e+10`` for ``12000000000.5``): :func:`csv_bytes` takes Arrow's text only where the layouts agree
(finite, not a whole number, magnitude in :data:`_ARROW_RANGE`) and Python's ``repr`` (what pandas writes)
for every other cell, so the file is the one pandas writes; tests/test_csv_text.py compares them byte for
byte over random tables of every kind of value.

Columns of float64, integers and booleans (numpy's or pandas' nullable ones) and text (``str`` or
missing) take this path; a table with any other column (dates, categories, mixed objects), with column
names that need quoting, or with one column (where the csv module quotes an empty field) is written by
pandas itself.
"""
from __future__ import annotations

import functools
import gzip
import os

import numpy as np
import pandas as pd

#: the characters that may make the csv module (pandas' QUOTE_MINIMAL) quote a field: which of them do
#: depends on the Python version (3.11 leaves a carriage return unquoted), so pandas is asked once
_CANDIDATES = (",", '"', "\n", "\r")
#: Arrow's layout of a float agrees with ``repr`` for finite, non-whole values of magnitude in this range
#: (below it Arrow writes 0.0000x where repr writes x e-05; from 1e10 it writes 1.2e+10 where repr writes
#: 12000000000.5: measured on 200 000 random values per decade, tests/test_csv_text.py)
_ARROW_RANGE = (1e-4, 1e10)


def _float_cells(values: np.ndarray):
    """The cells of a float64 column as pandas writes them (``repr``; ``""`` for NaN), as an Arrow array."""
    import pyarrow as pa
    import pyarrow.compute as pc

    mag = np.abs(values)
    with np.errstate(invalid="ignore"):
        arrow_ok = (mag >= _ARROW_RANGE[0]) & (mag < _ARROW_RANGE[1]) & (values != np.trunc(values))
    cells = pc.cast(pa.array(values), pa.large_string())
    if arrow_ok.all():
        return cells
    other = [repr(v) if v == v else "" for v in values[~arrow_ok].tolist()]
    return pc.replace_with_mask(cells, pa.array(~arrow_ok), pa.array(other, type=pa.large_string()))


@functools.lru_cache(maxsize=1)
def _special() -> tuple[str, ...]:
    """The characters of :data:`_CANDIDATES` that make pandas quote a field (asked once per process)."""
    return tuple(ch for ch in _CANDIDATES
                 if pd.DataFrame({"a": [f"x{ch}"], "b": [""]}).to_csv(index=False).startswith('a,b\n"'))


def _text_cells(values: pd.Series):
    """The cells of a column of text (``str`` or missing) with the csv module's minimal quoting."""
    import pyarrow as pa
    import pyarrow.compute as pc

    if isinstance(values.dtype, pd.StringDtype) and values.dtype.storage == "pyarrow":
        cells = pa.array(values.array, type=pa.large_string())      # Arrow's own text, no copy through Python
        if isinstance(cells, pa.ChunkedArray):
            cells = cells.combine_chunks()
    else:
        cells = pa.array(values.to_numpy(dtype=object), type=pa.large_string(), from_pandas=True)
    cells = cells.fill_null("")
    pattern = "[" + "".join({"\n": r"\n", "\r": r"\r"}.get(ch, ch) for ch in _special()) + "]"
    quote = pc.match_substring_regex(cells, pattern)
    if pc.any(quote).as_py():
        q, empty = pa.scalar('"', pa.large_string()), pa.scalar("", pa.large_string())
        quoted = pc.binary_join_element_wise(q, pc.replace_substring(cells, '"', '""'), q, empty)
        cells = pc.if_else(quote, quoted, cells)
    return cells


def _cells(col: pd.Series):
    """The column's cells as pandas writes them, or None when the column is not of a kind handled here."""
    import pyarrow as pa
    import pyarrow.compute as pc

    dtype = col.dtype
    if dtype == np.float64:
        return _float_cells(col.to_numpy())
    if pd.api.types.is_integer_dtype(dtype) and not isinstance(dtype, pd.CategoricalDtype):
        return pc.cast(pa.array(col, from_pandas=True), pa.large_string()).fill_null("")   # Int64: NA as ""
    if dtype == np.bool_ or isinstance(dtype, pd.BooleanDtype):
        flags = pa.array(col, type=pa.bool_(), from_pandas=True)
        return pc.if_else(flags, pa.scalar("True", pa.large_string()), pa.scalar("False", pa.large_string())
                          ).fill_null("")
    if isinstance(dtype, pd.StringDtype) or (dtype == np.dtype(object) and
                                             pd.api.types.infer_dtype(col, skipna=True) in ("string", "empty")):
        return _text_cells(col)
    return None


def _columns(frame: pd.DataFrame) -> list | None:
    """Every column's cells (Arrow arrays), or None when the table is one left to pandas."""
    names = list(frame.columns)
    if (len(names) < 2 or not all(isinstance(c, str) for c in names) or len(set(names)) < len(names)
            or any(ch in name for name in names for ch in _CANDIDATES)):
        return None
    columns = []
    for i in range(frame.shape[1]):
        cells = _cells(frame.iloc[:, i])
        if cells is None:
            return None
        columns.append(cells)
    return columns


def csv_bytes(frame: pd.DataFrame) -> bytes:
    """``frame.to_csv(index=False)`` as UTF-8 bytes (the same bytes; see the module's docstring)."""
    import pyarrow as pa
    import pyarrow.compute as pc

    columns = _columns(frame)
    if columns is None:
        return frame.to_csv(index=False).encode()
    head = (",".join(frame.columns) + "\n").encode()
    if not len(frame):
        return head
    newline, empty, comma = (pa.scalar(t, pa.large_string()) for t in ("\n", "", ","))
    columns[-1] = pc.binary_join_element_wise(columns[-1], newline, empty)     # each line's end
    lines = pc.binary_join_element_wise(*columns, comma)
    if hasattr(lines, "combine_chunks"):
        lines = lines.combine_chunks()
    offsets = np.frombuffer(lines.buffers()[1], dtype=np.int64, count=len(lines) + 1, offset=lines.offset * 8)
    return head + lines.buffers()[2].to_pybytes()[offsets[0]:offsets[-1]]


def write_csv(frame: pd.DataFrame, path: str | os.PathLike, gzip_level: int | None = None) -> None:
    """Write ``frame`` as :func:`csv_bytes` to ``path`` (gzip-compressed at ``gzip_level`` when given, with
    no file name or time in the gzip header, so that the bytes depend on the table alone)."""
    data = csv_bytes(frame)
    with open(path, "wb") as fh:
        if gzip_level is None:
            fh.write(data)
        else:
            with gzip.GzipFile(filename="", mode="wb", fileobj=fh, compresslevel=gzip_level, mtime=0) as gz:
                gz.write(data)
