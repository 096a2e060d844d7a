"""``jointbench estimate`` on awkward real-world inputs (issue 13, "Robust on real data").

Every bad input is one line on stderr starting ``jointbench: error:``, exit status 2, no traceback and
no output file; memory is planned before a fit; ``--window`` crops; a gated multisine is found and named;
MATLAB v7.3 files are read; ``--list`` imports none of the heavy libraries.
"""
from __future__ import annotations

import io
import re
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from numpy.lib import format as npf

from tests.estimate_data import gated_wrist, lti_ankle, one_blas_thread_per_test, run, save, tv_elbow  # noqa: F401 (autouse fixture)
from tests.multisine_data import multisine_impedance_trial

REPO = Path(__file__).resolve().parents[1]



def refused(tmp_path: Path, argv, *words) -> str:
    """Run, expect exit 2 with one error line (containing ``words``), no traceback, nothing written."""
    before = {p.name for p in tmp_path.iterdir()}
    code, out, err = run(argv)
    assert code == 2, (code, out, err)
    assert err.startswith("jointbench: error: ") and err.count("\n") == 1, err
    assert "Traceback" not in err + out and out == ""
    for w in words:
        assert w in err, (w, err)
    assert {p.name for p in tmp_path.iterdir()} == before          # no output, no temporary file
    return err


def write_csv(path: Path, **cols) -> Path:
    pd.DataFrame(cols).to_csv(path, index=False)
    return path


@pytest.fixture(scope="module")
def ankle():
    return lti_ankle(7, duration=10.0)


# ------------------------------------------------------------------------------- one line, exit 2
@pytest.mark.parametrize("name", ["fsewls", "irf2_ls", "kbr", "skirt"])
@pytest.mark.parametrize("level", [0.0, 3.5])
def test_zero_or_constant_torque(tmp_path, name, level):
    t = tv_elbow(1, duration=10.0) if name == "fsewls" else (
        multisine_impedance_trial(0.01, 0.8, 140) if name in ("kbr", "skirt") else lti_ankle(1))
    src = save(tmp_path / "r.npz", t.replace(torque=np.full(t.n, level)))
    refused(tmp_path, ["-e", name, "-i", src, "-o", tmp_path / "o.csv"], "torque is constant")


def test_kbr_on_two_samples(tmp_path):
    src = write_csv(tmp_path / "two.csv", time=[0.0, 0.01], angle=[0.0, 0.01], torque=[0.0, 1.0])
    refused(tmp_path, ["-e", "kbr", "-i", src, "-o", tmp_path / "o.csv"], "2 samples")


@pytest.mark.parametrize("name, setting", [("irf2_ls", "lag_before=inf"), ("spectral", "segment=inf"),
                                           ("kbr", "band=1,inf"), ("ibk_irf", "lag_after=1e400")])
def test_infinite_settings(tmp_path, ankle, name, setting):
    src = save(tmp_path / "r.npz", ankle)
    refused(tmp_path, ["-e", name, "-i", src, "-o", tmp_path / "o.csv", "--set", setting], "finite")


def test_lags_that_round_to_no_sample(tmp_path, ankle):
    src = save(tmp_path / "r.npz", ankle)
    refused(tmp_path, ["-e", "irf2_ls", "-i", src, "-o", tmp_path / "o.csv", "--decimate", "1500"],
            "less than half a sample")
    # a time column in milliseconds read as seconds: 500 Hz becomes 0.5 Hz
    ms = write_csv(tmp_path / "ms.csv", time=ankle.time * 1000, angle=ankle.angle, torque=ankle.torque)
    err = refused(tmp_path, ["-e", "irf2_ls", "-i", ms, "-o", tmp_path / "o.csv"], "lag_before", "milliseconds")
    assert "0.5 Hz" in err


@pytest.mark.parametrize("name, scale", [("kbr", 1e-160), ("irf2_ls", 1e-160), ("irf2_ls", 1e300),
                                         ("fsewls", 1e300)])
def test_values_outside_double_precision_comfort(tmp_path, name, scale):
    t = multisine_impedance_trial(0.01, 0.8, 140) if name == "kbr" else (
        tv_elbow(2, duration=10.0) if name == "fsewls" else lti_ankle(2))
    src = save(tmp_path / "r.npz", t.replace(angle=t.angle * scale, torque=t.torque * scale))
    refused(tmp_path, ["-e", name, "-i", src, "-o", tmp_path / "o.csv"], "check the units")


def test_npz_member_claiming_224_gib(tmp_path, ankle):
    path = tmp_path / "huge.npz"
    with zipfile.ZipFile(path, "w") as zf:
        for name, arr in (("time", ankle.time), ("torque", ankle.torque)):
            buf = io.BytesIO()
            np.save(buf, arr)
            zf.writestr(f"{name}.npy", buf.getvalue())
        buf = io.BytesIO()
        npf.write_array_header_2_0(buf, {"descr": "<f8", "fortran_order": False, "shape": (30_000_000_000,)})
        zf.writestr("angle.npy", buf.getvalue() + ankle.angle.tobytes())       # claims 224 GiB, holds 40 kB
    err = refused(tmp_path, ["-e", "irf2_ls", "-i", path, "-o", tmp_path / "o.csv"], "'angle'", "corrupt")
    assert "224 GiB" in err


def test_angle_and_Angle_both_present(tmp_path, ankle):
    src = write_csv(tmp_path / "r.csv", time=ankle.time, angle=ankle.angle, Angle=-ankle.angle, torque=ankle.torque)
    refused(tmp_path, ["-e", "irf2_ls", "-i", src, "-o", tmp_path / "o.csv"], "'angle'", "'Angle'")


def test_unwritable_output_is_refused_before_fitting(tmp_path, ankle):
    src = save(tmp_path / "r.npz", ankle)
    (tmp_path / "blocker").write_text("a file where a folder should be")
    refused(tmp_path, ["-e", "irf2_ls", "-i", src, "-o", tmp_path / "o.csv", "--plot", tmp_path / "blocker" / "f.png"],
            "cannot write")


# ------------------------------------------------------------------------------------------ memory
def test_kbr_plans_its_memory_and_names_the_rate_that_fits(tmp_path):
    t = multisine_impedance_trial(0.003, 0.035, 5.6, fs=2500.0, duration=40.0)     # 100 000 samples
    src = save(tmp_path / "fast.npz", t)
    # the exact kernel (one point per sample) needs an n x n eigenproblem: about 224 GiB
    err = refused(tmp_path, ["-e", "kbr", "-i", src, "-o", tmp_path / "o.csv", "--set", "kernel_points=100000"],
                  "GiB", "--decimate")
    assert "2500 Hz" in err


def test_kbr_at_the_native_rate_finishes(tmp_path):
    """A gated multisine at 2.5 kHz (the prediction used to fall back on a 74.5 GiB dense solve)."""
    t = gated_wrist(5, fs=2500, duration=25.0, quiet=2.5)
    src = save(tmp_path / "w.npz", t)
    code, out, err = run(["-e", "kbr", "-i", src, "-o", tmp_path / "o.csv"])
    assert code == 0, err
    assert "gated multisine: the angle is perturbed from 2.500 s to 22.500 s only" in out
    assert "2 whole periods of 10 s" in out
    frame = pd.read_csv(tmp_path / "o.csv")
    assert len(frame) == 50000 and frame["stiffness"].notna().all() and 1 < frame["stiffness"].mean() < 15


@pytest.mark.slow
def test_kbr_50s_at_2500Hz(tmp_path):
    """The case of the issue: 50 s at 2.5 kHz, multisine off for the first and last 5 s."""
    src = save(tmp_path / "w.npz", gated_wrist(6, fs=2500))
    code, out, err = run(["-e", "kbr", "-i", src, "-o", tmp_path / "o.csv"])
    assert code == 0, err
    assert len(pd.read_csv(tmp_path / "o.csv")) == 100000


# ---------------------------------------------------------------------------- window and gating
@pytest.fixture(scope="module")
def wrist(tmp_path_factory):
    return save(tmp_path_factory.mktemp("w") / "gated.npz", gated_wrist(4))


def test_window_crops_before_fitting(tmp_path, ankle):
    src = save(tmp_path / "r.npz", ankle)
    code, out, err = run(["-e", "irf2_ls", "-i", src, "-o", tmp_path / "o.csv", "--window", "2s:7500ms"])
    assert code == 0, err
    frame = pd.read_csv(tmp_path / "o.csv")
    assert len(frame) == round(5.5 * ankle.fs) and frame["time"].iloc[0] == pytest.approx(ankle.time[0] + 2.0)
    assert "fitted on 2.000 ... 7.500 s (2750 samples)" in out
    refused(tmp_path, ["-e", "irf2_ls", "-i", src, "-o", tmp_path / "o.csv", "--window", "5s:45s"], "10 s long")
    refused(tmp_path, ["-e", "irf2_ls", "-i", src, "-o", tmp_path / "o.csv", "--window", "5s:2s"], "after the start")


@pytest.mark.parametrize("name", ["skirt", "kbr"])
def test_gated_multisine_is_found_and_named(tmp_path, wrist, name):
    code, out, err = run(["-e", name, "-i", wrist, "-o", tmp_path / "o.csv", "--window", "5s:45s"])
    assert code == 0, err
    assert len(pd.read_csv(tmp_path / "o.csv")) == 2000                 # 40 s at 50 Hz
    code, out, err = run(["-e", name, "-i", wrist, "-o", tmp_path / "o.csv"])
    assert code == 0, err
    assert re.search(r"gated multisine: the angle is perturbed from [45]\.\d+ s to 4[45]\.\d+ s only; fitted on "
                     r"5\.000 \.\.\. 45\.000 s \(4 whole periods of 10 s\)", out), out
    # a window that keeps quiet seconds: the error names the gating and the window to use
    err = refused(tmp_path, ["-e", name, "-i", wrist, "-o", tmp_path / "x.csv", "--window", "0s:40s"],
                  "perturbed from")
    assert "--window" in err


# ----------------------------------------------------------------------------------- MATLAB v7.3
def save_mat73(path: Path, **variables) -> Path:
    """A MATLAB v7.3 file as MATLAB writes it: HDF5 with a 512-byte user block holding the MAT header,
    each variable a dataset (transposed: MATLAB is column-major) with its MATLAB_class."""
    h5py = pytest.importorskip("h5py")
    with h5py.File(path, "w", userblock_size=512) as f:
        for k, v in variables.items():
            d = f.create_dataset(k, data=np.atleast_2d(np.asarray(v, float)).T)
            d.attrs["MATLAB_class"] = np.bytes_("double")
        f.create_dataset("note", data=np.frombuffer(b"hello", np.uint8)[:, None].astype(np.uint16)).attrs[
            "MATLAB_class"] = np.bytes_("char")
    text = b"MATLAB 7.3 MAT-file, Platform: GLNXA64, Created on: Mon Jan  1 00:00:00 2024 HDF5 schema 1.00 ."
    with open(path, "r+b") as f:
        f.write(text.ljust(116, b" ") + b"\x00" * 8 + b"\x00\x02" + b"IM")
    return path


def test_matlab_v73_file(tmp_path, ankle):
    from jointbench.fitting import read as bio

    p = save_mat73(tmp_path / "r.mat", time=ankle.time, angle=ankle.angle, torque=ankle.torque)
    t = bio.read_trial(p)
    assert np.array_equal(t.angle, ankle.angle) and t.fs == ankle.fs
    arr = save_mat73(tmp_path / "a.mat", z=np.column_stack([ankle.angle, ankle.torque]), fs=500.0)
    t = bio.read_trial(arr, array="z")                                   # an N x 2 matrix in MATLAB
    assert np.array_equal(t.torque, ankle.torque)
    code, out, err = run(["-e", "ibk_irf", "-i", f"{arr}:z", "-o", tmp_path / "o.csv"])
    assert code == 0, err


# ------------------------------------------------------------------------------------ quick start
def test_list_imports_no_heavy_library():
    code = ("import sys; from jointbench.cli import main; main(['estimate', '--list']); "
            "heavy = [m for m in ('scipy', 'pandas', 'matplotlib', 'jointbench.estimators.kbr') if m in sys.modules]; "
            "print('HEAVY', heavy)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=REPO, check=True).stdout
    assert "HEAVY []" in out and "kbr" in out and "fsewls" in out
