"""MATLAB class objects in .mat files (issue 37): the REKLAB toolbox's ``nldat`` (and ``segdat``, ``tvdat``) read by
``jointbench estimate`` and the API through mat-io, channels by name, the rate from ``domainIncr``; an object of any
other class, or a file with objects and no mat-io, is one line naming the class.

The small files are written by mat-io itself (MATLAB is not here, and GNU Octave cannot save classdef objects);
REKLAB's own ``experimental_data.mat`` (MATLAB-written) pins the layout of a real file where it lies beside the
checkout (``../shared/data/reklab-ankle/``), against the same trials converted to plain arrays.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from jointbench import api
from jointbench.cli.command import main
from jointbench.core.ensemble import Ensemble
from jointbench.core.errors import InputError
from jointbench.fitting import read, read_matlab

matio = pytest.importorskip("matio", reason="mat-io not installed (pip install 'jointbench[matlab]')")
from matio.utils import MatlabOpaque  # noqa: E402

SHARED = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "reklab-ankle"
REKLAB_MAT = SHARED / "experimental_data.mat"
REKLAB_NPZ = SHARED / "ankle_stationary.npz"


def _cell(names):
    out = np.empty((1, len(names)), dtype=object)
    for i, n in enumerate(names):
        out[0, i] = np.array([n])
    return out


def nldat(data, names, incr=0.001, start=0.0, classname="nldat", **extra) -> MatlabOpaque:
    """A REKLAB data object as MATLAB saves its properties (``@nldat/nldat.m``, ``@nltop``)."""
    props = {"chanNames": _cell(names), "chanUnits": _cell(["Default Units"]), "domainIncr": np.array([[incr]]),
             "domainName": np.array(["Time (s)"]), "domainStart": np.atleast_2d(np.asarray(start, float)),
             "domainValues": np.array([[np.nan]]), "dataSet": np.asarray(data, float),
             "dataSize": np.array([np.shape(data)], float), "comment": np.array(["test"]),
             "version": np.array(["2.01"]), **extra}
    return MatlabOpaque(properties=props, classname=classname)


def param(name, value) -> MatlabOpaque:
    return MatlabOpaque(properties={"paramDefault": np.array([[np.nan]]), "paramHelp": np.array(["help"]),
                                    "paramLimits": np.array([[-np.inf, np.inf]]), "paramName": np.array([name]),
                                    "paramType": np.array(["number"]), "paramValue": np.atleast_2d(value)},
                        classname="param")


def save(path: Path, version="v7", **variables) -> Path:
    matio.save_to_mat(str(path), variables, version=version)
    return path


def ankle_like(n=3000, seed=0):
    """Angle (rad) and torque (N m) of a stiff joint, a little noise: something to fit."""
    rng = np.random.default_rng(seed)
    angle = np.convolve(rng.standard_normal(n), np.ones(5) / 5, "same") * 0.02
    torque = 80.0 * angle + 0.05 * rng.standard_normal(n)
    return angle, torque


@pytest.mark.parametrize("version", ["v7", "v7.3"])
def test_an_nldat_object_is_a_record_its_channels_by_name_its_rate_from_domainincr(tmp_path, version):
    angle, torque = ankle_like()
    path = save(tmp_path / "rec.mat", version, z=nldat(np.c_[torque, angle], ["tq1", "pos1"], incr=0.002, start=1.5),
                other=np.arange(4.0))
    t = read.read_trial(path, array="z")
    assert t.fs == 500.0 and t.n == 3000 and t.time[0] == 1.5 and t.name == "rec.mat:z"
    np.testing.assert_array_equal(t.angle, angle)          # pos1 is the angle although it is the second channel
    np.testing.assert_array_equal(t.torque, torque)
    assert np.allclose(np.diff(t.time), 0.002)


def test_two_unnamed_channels_are_input_then_output_and_ambiguous_names_are_one_line(tmp_path):
    angle, torque = ankle_like()
    path = save(tmp_path / "rec.mat", z=nldat(np.c_[angle, torque], ["z1", "z2"]),
                w=nldat(np.c_[angle, torque, angle], ["pos1", "tq1", "pos2"]))
    t = read.read_trial(path, array="z")                    # REKLAB's [input, output] order, as nldat([u y])
    np.testing.assert_array_equal(t.angle, angle)
    with pytest.raises(InputError) as exc:
        read.read_trial(path, array="w")
    text = str(exc.value)
    assert "\n" not in text and "'pos1', 'tq1', 'pos2'" in text and "nldat 'w'" in text


def test_a_segdat_is_one_record_per_segment(tmp_path):
    angle, torque = ankle_like(4000)
    # MATLAB saves parameterSet as a 1 x 2 param object array, which mat-io reads as an array of objects but cannot
    # write (nested object arrays fail in its writer): here a cell of the two, read back the same way
    pset = np.empty((1, 2), dtype=object)
    pset[0, 0], pset[0, 1] = param("onsetPointer", [[1], [2501]]), param("segLength", [[2000], [1500]])
    obj = nldat(np.c_[angle, torque], ["pos", "tq"], start=[[0.0], [10.0]], classname="segdat", parameterSet=pset,
                segInfo=np.empty((0, 0), dtype=object))
    path = save(tmp_path / "seg.mat", s=obj)
    trials = read.read_trials([read.parse_source(f"{path}:s")])
    assert [t.name for t in trials] == ["seg.mat:s[segment 1]", "seg.mat:s[segment 2]"]
    assert [t.n for t in trials] == [2000, 1500] and trials[1].time[0] == 10.0
    np.testing.assert_array_equal(trials[1].torque, torque[2500:4000])
    with pytest.raises(InputError, match="2 segments"):
        read.read_trial(path, array="s")


def test_an_nldat_of_several_realizations_is_an_ensemble(tmp_path):
    reals = [ankle_like(1000, seed=s) for s in range(3)]
    data = np.stack([np.c_[a, y] for a, y in reals], axis=2)            # samples x channels x realizations
    path = save(tmp_path / "ens.mat", e=nldat(data, ["pos", "tq"], classname="tvdat"))
    ens = api.read(f"{path}:e")
    assert isinstance(ens, Ensemble) and ens.size == 3 and ens.fs == 1000.0
    assert [t.name for t in ens.realizations] == ["ens.mat:e[0]", "ens.mat:e[1]", "ens.mat:e[2]"]
    np.testing.assert_array_equal(ens.realizations[2].torque, reals[2][1])
    with pytest.raises(InputError, match="3 realizations"):
        read.read_trial(path, array="e")


def test_an_object_of_another_class_is_one_line_naming_it(tmp_path, capsys):
    odd = MatlabOpaque(properties={"x": np.array([[1.0]])}, classname="nlbl")
    path = save(tmp_path / "odd.mat", m=odd, z=nldat(np.c_[ankle_like()], ["pos", "tq"]))
    with pytest.raises(InputError) as exc:
        read.read_trial(path, array="m")
    assert str(exc.value) == (f"{path}: 'm' is a MATLAB object of class nlbl: not a data class jointbench reads (it "
                              f"reads REKLAB's nldat, segdat, tvdat)")
    with pytest.raises(InputError) as exc:                  # a missing name lists the objects by class and channels
        read.read_trial(path, array="q")
    assert "m nlbl object" in str(exc.value) and "z nldat 3000×2 (pos, tq)" in str(exc.value)


def test_objects_without_mat_io_name_the_class_and_the_extra(tmp_path, monkeypatch):
    path = save(tmp_path / "rec.mat", z=nldat(np.c_[ankle_like()], ["pos1", "tq1"]), x=np.arange(3.0))
    monkeypatch.setattr(read_matlab, "load_matio", lambda: None)
    with pytest.raises(InputError) as exc:
        read.read_trial(path, array="z")
    text = str(exc.value)
    assert "\n" not in text and "'z' is a MATLAB object of class nldat" in text and "jointbench[matlab]" in text
    assert read.read_mat(path)["x"].ravel().tolist() == [0.0, 1.0, 2.0]     # the plain arrays are still read


def test_a_one_channel_nldat_is_a_recorded_scheduling_variable(tmp_path):
    """REKLAB's time-varying ankle trial keeps its scheduling variable as an nldat of its own (``sv`` beside
    ``io``): ``schedule='sv'`` reads its one channel."""
    angle, torque = ankle_like(4000)
    sv = np.linspace(-0.4, 0.2, 4000)
    path = save(tmp_path / "tv.mat", io=nldat(np.c_[angle, torque], ["posPert1", "tqPert1"]),
                sv=nldat(sv[:, None], ["Scheduling Variable (SV) - Ankle Position (rad)"]))
    [t] = api.read(f"{path}:io", schedule="sv")
    np.testing.assert_array_equal(t.channels["sv"], sv)


def test_the_command_fits_an_nldat_record(tmp_path, capsys):
    angle, torque = ankle_like(4000)
    path = save(tmp_path / "rec.mat", z=nldat(np.c_[angle, torque], ["posPert1", "tqPert1"]))
    assert main(["estimate", "-i", f"{path}:z", "-e", "irf2_ls", "-o", str(tmp_path / "out.csv")]) == 0
    assert "rec.mat:z  4000 samples at 1000 Hz" in capsys.readouterr().out


@pytest.mark.skipif(not REKLAB_MAT.is_file() or not REKLAB_NPZ.is_file(),
                    reason="../shared/data/reklab-ankle/experimental_data.mat absent (developers' checkout only)")
def test_reklabs_own_file_reads_as_its_arrays_and_fits(tmp_path, capsys):
    """REKLAB's MATLAB-written file: five nldat objects (pos1, tq1; domainIncr 0.001) equal, sample for sample, to
    the same trials as plain arrays; and the issue's acceptance command fits it."""
    variables = read.read_mat(REKLAB_MAT)
    plain = np.load(REKLAB_NPZ)
    for k in ("z_pf", "z_pf2", "z_df", "z_df2", "z_df3"):
        t = read.read_trial(REKLAB_MAT, array=k)
        assert variables[k].classname == "nldat" and variables[k].channels == ("pos1", "tq1") and t.fs == 1000.0
        np.testing.assert_array_equal(np.c_[t.angle, t.torque], plain[k])
    args = ["-e", "parallel_cascade", "--decimate", "10", "--torque-sign", "-1"]
    assert main(["estimate", "-i", f"{REKLAB_MAT}:z_pf2", *args, "-o", str(tmp_path / "mat.csv")]) == 0
    assert main(["estimate", "-i", f"{REKLAB_NPZ}:z_pf2", *args, "-o", str(tmp_path / "npz.csv")]) == 0
    out = capsys.readouterr().out.splitlines()
    estimates = [line for line in out if line.startswith("estimate:")]
    assert len(estimates) == 2 and estimates[0] == estimates[1]
