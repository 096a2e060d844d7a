"""Input files: their contents key the cache (an edited profile is recomputed), and hostile ones (devices,
FIFOs, zip bombs, huge CSVs, corrupt HDF5) are refused in one line before anything is loaded (issue 20)."""
from __future__ import annotations

import os
import zipfile

import numpy as np
import pytest
import yaml

from jointbench.fitting import read, read_limits
from jointbench.benchmarks.study import run_study
from jointbench.core.errors import ConfigError, InputError
from tests.harness_studies import tiny_study


def _profile(path, level: float):
    path.write_text("time,value\n0,{0}\n10,{0}\n".format(level))
    return path


def _profile_study(tmp_path, prof):
    path = tiny_study(tmp_path / "cfg", seeds=1)
    data = yaml.safe_load(path.read_text())
    data["parts"]["fit"]["experiment"]["joint"] = {"model": "time_varying", "I": 0.01, "B": 0.5,
                                                   "K": {"shape": "file", "path": str(prof)}}
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def _k(run) -> float:
    return float(run.rows.loc[run.rows["metric"] == "K", "value"].iloc[0])


def test_an_edited_profile_is_recomputed_not_served_from_the_cache(tmp_path):
    prof = _profile(tmp_path / "k.csv", 40)
    study = _profile_study(tmp_path, prof)
    first = run_study(study, out_root=tmp_path / "out", serial=True, progress=False)
    _profile(prof, 80)                                   # no sha256 pin in the config
    second = run_study(study, out_root=tmp_path / "out", serial=True, progress=False)
    assert not second.results[0].cached
    assert abs(_k(first) - 40) < 5 and abs(_k(second) - 80) < 8
    os.utime(prof, (1, 1))                               # the same contents, touched: served
    third = run_study(study, out_root=tmp_path / "out", serial=True, progress=False)
    assert third.results[0].cached and _k(third) == _k(second)


def test_the_key_holds_the_contents_of_each_input_file_by_its_configured_name(tmp_path):
    from jointbench.benchmarks.config import load_study
    from jointbench.benchmarks.harness.case import content_hash
    from jointbench.benchmarks.runner import expand

    prof = _profile(tmp_path / "k.csv", 40)
    [case] = expand(load_study(_profile_study(tmp_path, prof)))
    material = case.key_material()
    assert material["inputs"] == [[str(prof), content_hash(str(prof))]]
    import hashlib
    assert content_hash(str(prof)) == hashlib.sha256(prof.read_bytes()).hexdigest()


@pytest.mark.parametrize("make, words", [
    (lambda p: os.symlink("/dev/zero", p), "is a device, not a regular file"),
    (lambda p: os.mkfifo(p), "is a FIFO (named pipe), not a regular file"),
    (lambda p: p.write_bytes("time,value\n# Müller\n0,1\n9,2\n".encode("latin-1")),
     "not UTF-8 text: byte 0xfc at line 2"),
])
def test_a_hostile_profile_file_is_one_line(tmp_path, make, words):
    from jointbench.sims.profile_file import FromFile

    make(tmp_path / "k.csv")
    with pytest.raises(ConfigError, match=__import__("re").escape(words)):
        FromFile(path=str(tmp_path / "k.csv"))


def test_a_profile_with_too_many_rows_is_refused_before_parsing(tmp_path, monkeypatch):
    from jointbench.sims import profile_file

    monkeypatch.setattr(profile_file, "MAX_PROFILE_ROWS", 100)
    p = tmp_path / "k.csv"
    p.write_text("time,value\n" + "".join(f"{i},1\n" for i in range(5000)))
    with pytest.raises(ConfigError, match=r"k\.csv: 5001 lines, more than the 100 rows a profile may have"):
        profile_file.FromFile(path=str(p))


@pytest.mark.parametrize("suffix", [".csv", ".npz", ".mat"])
@pytest.mark.parametrize("kind", ["/dev/zero", "FIFO"])
def test_a_recording_that_is_a_device_or_fifo_is_never_opened(tmp_path, suffix, kind):
    p = tmp_path / f"rec{suffix}"
    os.symlink("/dev/zero", p) if kind == "/dev/zero" else os.mkfifo(p)
    with pytest.raises(InputError, match="not a regular file"):
        read.read_trial(p)


def test_a_zip_bomb_is_refused_from_its_headers(tmp_path, monkeypatch):
    """Members that would not fit in half the memory available are refused from their headers, before they
    are decompressed (the memory is lowered here so that the bomb is small; the real one is 2 GiB of zeros
    per member)."""
    from numpy.lib import format as npf

    monkeypatch.setattr(read_limits, "available_memory", lambda: 2_000_000)
    p = tmp_path / "bomb.npz"
    n = 200_000
    with zipfile.ZipFile(p, "w", compression=zipfile.ZIP_DEFLATED) as zf:
        for name in ("angle", "torque"):
            with zf.open(f"{name}.npy", "w") as f:
                npf.write_array_header_1_0(f, {"descr": "<f8", "fortran_order": False, "shape": (n,)})
                f.write(bytes(8 * n))
    assert p.stat().st_size < 10_000                    # a few kB on disk
    with pytest.raises(InputError, match=r"bomb\.npz: member '(angle|torque)' is 1\.53 MiB \(200000\), more than "
                                         r"half the memory available \(1\.91 MiB\)"):
        read.read_trial(p)


def test_a_csv_too_large_for_the_memory_is_refused_before_pandas_reads_it(tmp_path, monkeypatch):
    monkeypatch.setattr(read_limits, "available_memory", lambda: 1_000_000)    # 5001 lines x 3 need 1.8 MB
    p = tmp_path / "big.csv"
    p.write_text("time,angle,torque\n" + "".join(f"{i / 1000},0.01,0.5\n" for i in range(5000)))
    with pytest.raises(InputError, match=r"big\.csv: reading it needs more than .* \(5001 lines so far, 3 columns\), "
                                         r"more than half the memory available"):
        read.read_trial(p)


def test_a_csv_that_is_not_utf8_is_one_line(tmp_path):
    p = tmp_path / "rec.csv"
    p.write_bytes("time,angle,torque\n0,0,0\n0.002,0.1,1\n".encode("utf-16"))
    with pytest.raises(InputError, match=r"rec\.csv: the file is UTF-16 text"):
        read.read_trial(p)


@pytest.mark.parametrize("body", [b"\x89HDF\r\n\x1a\n" + bytes(range(256)) * 12, bytes(range(256)) * 16])
def test_a_corrupt_hdf5_mat_file_is_one_line(tmp_path, body):
    p = tmp_path / "rec.mat"
    header = b"MATLAB 7.3 MAT-file, Platform: GLNXA64, Created on: Mon Jan  1 00:00:00 2024 HDF5 schema 1.00 ."
    p.write_bytes(header.ljust(512, b" ") + body)
    with pytest.raises(InputError) as exc:
        read.read_trial(p)
    assert str(p) in str(exc.value) and "\n" not in str(exc.value)


def test_an_npz_member_larger_than_the_limit_in_an_ensemble_file(tmp_path, monkeypatch):
    monkeypatch.setattr(read_limits, "available_memory", lambda: 20_000)          # a member is 12 000 bytes
    p = tmp_path / "ens.npz"
    np.savez(p, angle=np.zeros((500, 3)), torque=np.zeros((500, 3)), fs=500.0)
    from jointbench.fitting.read_ensemble import read_ensemble

    with pytest.raises(InputError, match=r"ens\.npz: member '(angle|torque)' is 11\.7 KiB \(500x3\), more than half"):
        read_ensemble(p)
