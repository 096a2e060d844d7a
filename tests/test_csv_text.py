"""jointbench.core.csv_text writes the bytes pandas writes: random tables of every kind of value, the layouts
where Arrow's float text differs from Python's, and the tables it leaves to pandas."""
import gzip

import numpy as np
import pandas as pd
import pytest

from jointbench.core import csv_text
from jointbench.core.csv_text import csv_bytes, write_csv

#: floats whose text Arrow lays out otherwise than ``repr`` (the whole numbers, the small and the large),
#: the bounds of the range where it agrees, and the values without digits
EDGES = [0.0, -0.0, 1.0, -3.0, 2.0 ** 53, 2.0 ** 53 + 2, 1e15, 1e16, -1e16, 1e15 + 0.5, 999999999999999.9,
         1e10, 1e10 + 0.5, 9999999999.999998, 12345678901.25,
         1e-4, -1e-4, 0.0001234, 9.999999999999999e-05, 1e-5, 1.5e-7, 5e-324, -1e-310, 1e22, 1e300,
         1.7976931348623157e308, 123456789012345680.0, 0.1, 1 / 3, 2.5, 1.7000000000000002,
         np.inf, -np.inf, np.nan]


def _same(frame, fast=True):
    """The bytes of pandas; ``fast``: by the Arrow path (not by falling back on pandas)."""
    assert (csv_text._columns(frame) is not None) == fast
    assert csv_bytes(frame) == frame.to_csv(index=False).encode()


@pytest.mark.parametrize("seed", range(4))
def test_random_tables_of_every_kind_are_written_as_pandas_writes_them(seed):
    rng = np.random.default_rng(seed)
    n = 5000
    wide = 10.0 ** rng.uniform(-320, 308, n) * rng.choice([-1.0, 1.0], n)        # every magnitude
    near = rng.normal(0, 1, n) * 10.0 ** rng.integers(-6, 18, n)                 # around the range's bounds
    decades = 10.0 ** rng.uniform(8, 12, n)                                      # around 1e10
    whole = np.round(rng.normal(0, 1e4, n))                                      # whole numbers
    grid = np.arange(n) / 2500.0                                                 # a time axis at 2.5 kHz
    edges = np.resize(np.array(EDGES), n)
    rng.shuffle(edges)
    words = np.array(["a", "", "with, comma", 'say "hi"', "two\nlines", "cr\rhere", "ünïcode", " space ",
                      "ends,", '"'], dtype=object)
    text = words[rng.integers(0, len(words), n)]
    text[rng.random(n) < 0.1] = None
    frame = pd.DataFrame({"wide": wide, "near": near, "decades": decades, "whole": whole, "t": grid, "edges": edges,
                          "i": rng.integers(-10 ** 12, 10 ** 12, n), "u8": rng.integers(0, 255, n).astype(np.uint8),
                          "flag": rng.random(n) < 0.5, "text": text, "none": [None] * n,
                          "seed": pd.array(np.where(rng.random(n) < 0.2, None, rng.integers(0, 99, n)), dtype="Int64"),
                          "chosen": pd.array(np.where(rng.random(n) < 0.2, None, rng.random(n) < 0.5),
                                             dtype="boolean")})
    _same(frame)
    _same(frame.iloc[rng.permutation(n)[:777]])                                 # a view, another order
    _same(frame.iloc[:0])                                                       # the header alone
    _same(frame.astype({"text": object}))                                       # text as Python objects


def test_every_edge_value_alone_and_in_company():
    for v in EDGES:
        _same(pd.DataFrame({"x": [v, v], "y": [0.5, v]}))
    _same(pd.DataFrame({"x": EDGES, "y": EDGES[::-1]}))


@pytest.mark.parametrize("frame", [
    pd.DataFrame({"only": [1.0, np.nan, 3.0]}),                                   # one column: "" is quoted
    pd.DataFrame({"a,b": [1.0], "c": [2.0]}),                                      # a name that needs quoting
    pd.DataFrame({"d": pd.to_datetime(["2026-12-04", "2026-12-05"]), "x": [1.0, 2.0]}),
    pd.DataFrame({"c": pd.Categorical(["a", "b"]), "x": [1.0, 2.0]}),
    pd.DataFrame({"m": [1, "a"], "x": [1.0, 2.0]}, dtype=object),                 # mixed objects
    pd.DataFrame({"f": np.array([0.1, 1e-5], dtype=np.float32), "x": [1.0, 2.0]}),
    pd.DataFrame({"b": [True, None], "x": [1.0, 2.0]}, dtype=object),             # flags as objects
    pd.DataFrame([[1.0, 2.0]], columns=["x", "x"]),                                # duplicate names
    pd.DataFrame([[1.0, 2.0]], columns=[1, 2]),                                    # names that are not text
], ids=["one-column", "quoted-name", "dates", "category", "mixed", "float32", "object-bool",
        "duplicate-names", "int-names"])
def test_the_tables_left_to_pandas_are_still_what_pandas_writes(frame):
    _same(frame, fast=False)


def test_the_fast_path_takes_the_numbers_and_the_text(monkeypatch):
    """The tables of the harness (floats, integers, flags, text) do not fall back on pandas."""
    def refuse(*a, **k):
        raise AssertionError("fell back on pandas")

    frame = pd.DataFrame({"x": [0.5, 3.0], "n": [1, 2], "ok": [True, False], "s": ["a", None]})
    expected = frame.to_csv(index=False).encode()
    monkeypatch.setattr(pd.DataFrame, "to_csv", refuse)
    assert csv_bytes(frame) == expected


def test_gzip_bytes_depend_on_the_table_alone(tmp_path):
    frame = pd.DataFrame({"t": np.arange(100) / 3, "s": ["x"] * 100})
    write_csv(frame, tmp_path / "a.csv.gz", gzip_level=6)
    write_csv(frame, tmp_path / "other-name.csv.gz", gzip_level=6)
    a, b = (tmp_path / "a.csv.gz").read_bytes(), (tmp_path / "other-name.csv.gz").read_bytes()
    assert a == b and gzip.decompress(a) == frame.to_csv(index=False).encode()
    write_csv(frame, tmp_path / "plain.csv")
    assert (tmp_path / "plain.csv").read_bytes() == csv_text.csv_bytes(frame)
    assert pd.read_csv(tmp_path / "a.csv.gz").equals(pd.read_csv(tmp_path / "plain.csv"))


@pytest.mark.parametrize("dtype", ["str", pd.StringDtype("python", na_value=np.nan), object])
def test_text_columns_are_written_as_pandas_writes_them(dtype):
    text = ["plain", np.nan, 'a "quoted" one', "comma, inside", "new\nline", "", "é ω"] * 3
    frame = pd.DataFrame({"t": pd.Series(text, dtype=dtype), "x": np.arange(len(text), dtype=float) / 7})
    assert csv_bytes(frame) == frame.to_csv(index=False).encode()
    assert csv_bytes(frame.iloc[5:9]) == frame.iloc[5:9].to_csv(index=False).encode()    # an offset slice
