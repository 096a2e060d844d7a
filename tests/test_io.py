"""Reading recordings (jointbench.fitting.read): round trips through CSV, NPZ and .mat, and every input error."""
import re
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from scipy import io as sio

from jointbench.fitting import read
from jointbench.core.errors import InputError
from jointbench.core.types import Trial


@pytest.fixture
def trial():
    rng = np.random.default_rng(0)
    n = 500
    return Trial.from_arrays(0.1 + 0.01 * rng.standard_normal(n), -3 + rng.standard_normal(n),
                             fs=1000.0, t0=0.25, name="rec")


def _same(a: Trial, b: Trial):
    assert a.fs == b.fs
    assert np.array_equal(a.time, b.time)
    assert np.array_equal(a.angle, b.angle)
    assert np.array_equal(a.torque, b.torque)
    assert b.imposed == "angle"


def _write(path: Path, **cols):
    """Write columns/variables to CSV, NPZ or MAT according to the suffix."""
    if path.suffix == ".csv":
        pd.DataFrame(cols).to_csv(path, index=False)
    elif path.suffix == ".npz":
        np.savez(path, **cols)
    else:
        sio.savemat(path, cols)
    return path


def _cols(t: Trial):
    return {"time": t.time, "angle": t.angle, "torque": t.torque}


def err(path) -> str:
    """Regex matching the file's name at the start of a message."""
    return "^" + re.escape(str(path)) + ": "


@pytest.mark.parametrize("suffix", [".csv", ".npz", ".mat"])
def test_round_trip_columns(tmp_path, trial, suffix):
    p = _write(tmp_path / f"rec{suffix}", **_cols(trial), emg=np.zeros(trial.n))
    got = read.read_trial(p)
    _same(trial, got)
    assert got.name == f"rec{suffix}"


@pytest.mark.parametrize("suffix", [".npz", ".mat"])
def test_round_trip_array_layout(tmp_path, trial, suffix):
    p = _write(tmp_path / f"rec{suffix}", z=np.column_stack([trial.angle, trial.torque]), fs=1000.0)
    got = read.read_trial(p, array="z")
    assert got.name == f"rec{suffix}:z"
    _same(Trial.from_arrays(trial.angle, trial.torque, fs=1000.0), got)  # time starts at 0
    # the rate may instead come from the caller; a matching rate is accepted too
    p2 = _write(tmp_path / f"nofs{suffix}", z=np.column_stack([trial.angle, trial.torque]))
    _same(got, read.read_trial(p2, array="z", fs=1000))
    _same(got, read.read_trial(p, array="z", fs=1000))


def test_columns_without_time_use_fs(tmp_path, trial):
    p = _write(tmp_path / "r.npz", angle=trial.angle, torque=trial.torque, fs=1000.0)
    _same(Trial.from_arrays(trial.angle, trial.torque, fs=1000.0), read.read_trial(p))


def test_mat_shapes_squeeze(tmp_path, trial):
    # savemat stores 1-D arrays as 1×N rows; N×1 columns must work as well
    p = _write(tmp_path / "c.mat", time=trial.time[:, None], angle=trial.angle[:, None],
               torque=trial.torque[None, :])
    _same(trial, read.read_trial(p))


def test_csv_header_case_blanks_comments_and_rounded_time(tmp_path):
    n, fs = 2000, 2048.0
    text = "# recorded 2024\n Time , ANGLE,torque,emg\n" + "".join(
        f"{k / fs:.6f}, {0.01 * np.sin(k / 7):.9f}, {np.cos(k / 5):.9f}, 1\n" for k in range(n))
    p = tmp_path / "r.csv"
    p.write_text(text)
    t = read.read_trial(p)
    assert t.fs == 2048.0 and t.n == n
    assert np.allclose(t.time, np.arange(n) / fs, atol=1e-6)


def test_parse_source():
    assert read.parse_source("a/b.npz:z_pf") == read.Source(Path("a/b.npz"), "z_pf")
    assert read.parse_source("a/b.npz", "z") == read.Source(Path("a/b.npz"), "z")
    assert read.parse_source("b.csv") == read.Source(Path("b.csv"), None)
    assert read.parse_source("C:/data/b.npz").array is None  # a drive letter is not an array
    assert read.parse_source("b.npz:z").label == "b.npz:z"


def test_existing_file_with_colon_is_a_file(tmp_path, trial):
    p = _write(tmp_path / "x.npz:y", **_cols(trial))  # odd but legal name
    assert read.parse_source(str(p)) == read.Source(p, None)


# --- errors ---------------------------------------------------------------------------------------

def test_missing_file(tmp_path):
    p = tmp_path / "nope.csv"
    with pytest.raises(InputError, match=err(p) + "no such file"):
        read.read_trial(p)


def test_unknown_extension(tmp_path):
    p = tmp_path / "r.xlsx"
    p.write_text("x")
    with pytest.raises(InputError, match=err(p) + r"unknown file type '\.xlsx'; supported: \.csv, \.npz, \.mat"):
        read.read_trial(p)


@pytest.mark.parametrize("suffix", [".csv", ".npz", ".mat"])
def test_missing_column_lists_what_is_there(tmp_path, trial, suffix):
    p = _write(tmp_path / f"r{suffix}", time=trial.time, angle=trial.angle, force=trial.torque)
    with pytest.raises(InputError, match=err(p) + r"missing (column|variable) 'torque'; .*found: .*force"):
        read.read_trial(p)


def test_missing_columns_suggest_arrays(tmp_path, trial):
    p = _write(tmp_path / "r.npz", z_pf=np.column_stack([trial.angle, trial.torque]))
    with pytest.raises(InputError, match=err(p) + r"missing variables 'time', 'angle', 'torque'.*"
                                       r"--array NAME or FILE:NAME \(candidates: z_pf\)"):
        read.read_trial(p)


@pytest.mark.parametrize("suffix", [".csv", ".npz", ".mat"])
@pytest.mark.parametrize("bad", [np.nan, np.inf])
def test_non_finite(tmp_path, trial, suffix, bad):
    y = trial.torque.copy()
    y[[7, 30, 31]] = bad
    p = _write(tmp_path / f"r{suffix}", time=trial.time, angle=trial.angle, torque=y)
    with pytest.raises(InputError, match=err(p) + r".*'torque' has 3 non-finite value\(s\).*first at sample 7"):
        read.read_trial(p)


def test_non_finite_time_and_empty_csv_cell(tmp_path, trial):
    t = trial.time.copy()
    t[4] = np.nan
    p = _write(tmp_path / "r.npz", time=t, angle=trial.angle, torque=trial.torque)
    with pytest.raises(InputError, match=err(p) + r"'time' has 1 non-finite.*first at sample 4"):
        read.read_trial(p)
    p = tmp_path / "e.csv"
    p.write_text("time,angle,torque\n0,1,2\n0.001,,2\n0.002,1,2\n")
    with pytest.raises(InputError, match=err(p) + r".*'angle' has 1 non-finite value\(s\).*first at sample 1"):
        read.read_trial(p)


def test_non_numeric_csv_value(tmp_path):
    p = tmp_path / "r.csv"
    p.write_text("time,angle,torque\n0,1,2\n0.001,abc,2\n")
    with pytest.raises(InputError, match=err(p) + r"column 'angle' has a non-numeric value 'abc' at sample 1"):
        read.read_trial(p)


@pytest.mark.parametrize("suffix", [".csv", ".npz", ".mat"])
def test_non_uniform_time(tmp_path, trial, suffix):
    t = np.delete(trial.time, 100)  # a dropped sample
    p = _write(tmp_path / f"r{suffix}", time=t, angle=trial.angle[:-1], torque=trial.torque[:-1])
    with pytest.raises(InputError, match=err(p) + r"time is not uniform: step 0.002 s between samples 99 and 100"):
        read.read_trial(p)


def test_non_increasing_time(tmp_path, trial):
    t = trial.time.copy()
    t[[10, 11]] = t[[11, 10]]
    p = _write(tmp_path / "r.npz", time=t, angle=trial.angle, torque=trial.torque)
    with pytest.raises(InputError,
                       match=err(p) + r"time is not increasing: .* at sample 10 is followed by .* at sample 11"):
        read.read_trial(p)


@pytest.mark.parametrize("suffix", [".npz", ".mat"])
def test_mismatched_lengths(tmp_path, trial, suffix):
    p = _write(tmp_path / f"r{suffix}", time=trial.time, angle=trial.angle, torque=trial.torque[:-5])
    with pytest.raises(InputError, match=err(p) + r".*mismatched lengths: time 500, angle 500, torque 495"):
        read.read_trial(p)


@pytest.mark.parametrize("suffix", [".csv", ".npz"])
def test_too_short(tmp_path, suffix):
    p = _write(tmp_path / f"r{suffix}", time=[0.0], angle=[0.1], torque=[1.0])
    with pytest.raises(InputError, match=err(p) + r".*at least 2 samples, got 1"):
        read.read_trial(p)
    q = _write(tmp_path / f"z{suffix}", z=np.zeros((1, 2)), fs=100.0) if suffix == ".npz" else None
    if q is not None:
        with pytest.raises(InputError, match=err(q) + r".*at least 2 samples, got 1"):
            read.read_trial(q, array="z")


def test_empty_csv_and_headerless_csv(tmp_path):
    p = tmp_path / "e.csv"
    p.write_text("")
    with pytest.raises(InputError, match=err(p) + "the file is empty"):
        read.read_trial(p)
    p = tmp_path / "h.csv"
    p.write_text("0,0.1,2\n0.001,0.1,2\n")
    with pytest.raises(InputError, match=err(p) + r"no column named time, angle, torque .*found: 0, 0.1, 2"):
        read.read_trial(p)


def test_different_sampling_rates(tmp_path, trial):
    a = _write(tmp_path / "a.npz", **_cols(trial))
    slow = Trial.from_arrays(trial.angle, trial.torque, fs=500.0)
    b = _write(tmp_path / "b.npz", **_cols(slow))
    with pytest.raises(InputError, match=r"different sampling rates \(a.npz at 1000 Hz, b.npz at 500 Hz\)"):
        read.read_trials([a, b])
    assert len(read.read_trials([a, a])) == 2


@pytest.mark.parametrize("shape", [(500, 3), (500,), (2, 500)])
def test_array_wrong_shape(tmp_path, shape):
    p = _write(tmp_path / "r.npz", z=np.zeros(shape), fs=1000.0)
    with pytest.raises(InputError, match=err(p) + r"array 'z' must be N×2 \[angle, torque\], got shape"):
        read.read_trial(p, array="z")


def test_array_missing_lists_candidates(tmp_path):
    p = _write(tmp_path / "r.mat", z_pf=np.zeros((10, 2)), fs=1000.0)
    with pytest.raises(InputError, match=err(p) + r"no array 'z_df'.*N×2 arrays there: z_pf"):
        read.read_trial(p, array="z_df")


def test_array_without_fs(tmp_path):
    p = _write(tmp_path / "r.npz", z=np.zeros((10, 2)))
    with pytest.raises(InputError, match=err(p) + r"no sampling rate for array 'z'.*--fs"):
        read.read_trial(p, array="z")


def test_fs_conflicts(tmp_path, trial):
    p = _write(tmp_path / "r.npz", z=np.zeros((10, 2)), fs=1000.0)
    with pytest.raises(InputError, match=err(p) + r"the file says fs = 1000 Hz but 500 Hz was given"):
        read.read_trial(p, array="z", fs=500)
    q = _write(tmp_path / "t.csv", **_cols(trial))
    with pytest.raises(InputError, match=err(q) + r"the time column gives 1000 Hz .* given as 250 Hz"):
        read.read_trial(q, fs=250)
    r = _write(tmp_path / "f.npz", z=np.zeros((10, 2)), fs=np.array([1.0, 2.0]))
    with pytest.raises(InputError, match=err(r) + r"'fs' must be a scalar"):
        read.read_trial(r, array="z")


def test_array_with_csv_and_unreadable_files(tmp_path, trial):
    p = _write(tmp_path / "r.csv", **_cols(trial))
    with pytest.raises(InputError, match=err(p) + r"an array name \('z'\) applies to .npz and .mat files only"):
        read.read_trial(p, array="z")
    bad = tmp_path / "bad.npz"
    bad.write_bytes(b"not a zip file")
    with pytest.raises(InputError, match=err(bad) + "cannot read as NPZ"):
        read.read_trial(bad)
    bad = tmp_path / "bad.mat"
    bad.write_bytes(b"\x00" * 10)
    with pytest.raises(InputError, match=err(bad) + "cannot read as a MATLAB .mat file"):
        read.read_trial(bad)


def test_non_numeric_variable(tmp_path, trial):
    p = _write(tmp_path / "r.npz", time=trial.time, angle=trial.angle, torque=np.array(["a"] * trial.n))
    with pytest.raises(InputError, match=err(p) + r"'torque' is not a numeric array"):
        read.read_trial(p)
