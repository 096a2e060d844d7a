"""``jointbench estimate --schedule`` (jointbench/fitting/schedule.py): a parameter-varying fit of a recording,
K printed at chosen values of the scheduling variable with intervals."""
from __future__ import annotations

import re

import pandas as pd
import pytest

from jointbench import sims
from tests.test_cli_estimate import cli


@pytest.fixture(scope="module")
def recording(tmp_path_factory):
    """A 60 s ankle trial at 1 kHz with K(theta) = 100 + 150 theta + 200 theta^2 and a slow movement, as a CSV
    with a further column 'position' (the slow movement as a lab would record it separately)."""
    j = {"model": "position_dependent", "I": 0.01, "B": 0.8, "K": {"polynomial": [100, 150, 200]},
         "angle_range": [-0.6, 0.4]}
    pert = {"kind": "moving", "movement": {"shape": "sine", "mean": -0.105, "amplitude": 0.305, "frequency": 0.1},
            "perturbation": {"kind": "pralds", "rms": 0.02, "min_hold": "20 ms", "max_hold": "200 ms",
                             "smoothing": "20 Hz"}}
    e = sims.Experiment.from_mapping({"joint": j, "apparatus": {"kind": "position_servo", "damping": 30},
                                      "perturbation": pert, "fs_sim": 1000, "duration": 62,
                                      "acquisition": {"detrend": False, "trim": "1 s"}})
    tr = sims.simulate(e, 0)
    path = tmp_path_factory.mktemp("sched") / "ankle.csv"
    pd.DataFrame({"time": tr.time, "angle": tr.angle, "torque": tr.torque,
                  "position": tr.truth.signals["scheduling"]}).to_csv(path, index=False)
    return path


def k_lines(out: str) -> list[tuple[float, float, float, float]]:
    return [tuple(map(float, m)) for m in
            re.findall(r"^\s+(\S+)\s+K = (\S+) \[(\S+), (\S+)\] N\.m/rad", out, re.M)]


@pytest.mark.parametrize("schedule", ["angle_slow", "position"])
def test_schedule_prints_k_at_chosen_values(recording, tmp_path, capsys, schedule):
    rc = cli(["-e", "pv_irf", "-i", recording, "-o", tmp_path / "out.csv", "--decimate", "10",
              "--set", "n_basis=3", "--schedule", schedule, "--at=-0.3,0,0.15"], capsys)
    out = capsys.readouterr().out
    assert rc == 0, out
    assert f"K at chosen values of the scheduling variable '{schedule}'" in out
    rows = k_lines(out)
    assert [r[0] for r in rows] == [-0.3, 0.0, 0.15]
    for v, k, lo, hi in rows:
        assert lo < k < hi and abs(k - (100 + 150 * v + 200 * v * v)) < 3.0
    resp = pd.read_csv(tmp_path / "out_response.csv")       # K over the visited range with its band
    assert list(resp.columns) == ["schedule", "stiffness", "stiffness_lo", "stiffness_hi"]
    assert {"schedule", "stiffness_lo"} <= set(pd.read_csv(tmp_path / "out.csv").columns)


def test_schedule_default_values_and_errors(recording, tmp_path, capsys):
    assert cli(["-e", "pv_irf", "-i", recording, "-o", tmp_path / "a.csv", "--decimate", "10",
                "--schedule", "angle_slow"], capsys) == 0
    assert len(k_lines(capsys.readouterr().out)) == 5
    assert cli(["-e", "irf2_ls", "-i", recording, "-o", tmp_path / "b.csv", "--schedule", "angle_slow"], capsys) == 2
    assert "estimator 'irf2_ls' takes no scheduling variable; parameter-varying estimators: pv_irf" in \
        capsys.readouterr().err
    assert cli(["-e", "pv_irf", "-i", recording, "-o", tmp_path / "c.csv", "--schedule", "emg"], capsys) == 2
    assert "has no column or array 'emg'; it has: angle, torque, position" in capsys.readouterr().err
    assert cli(["-e", "pv_irf", "-i", recording, "-o", tmp_path / "d.csv", "--at", "0.1"], capsys) == 2
    assert "--at: needs --schedule" in capsys.readouterr().err
    assert cli(["-e", "pv_irf", "-i", recording, "-o", tmp_path / "e.csv", "--schedule", "angle", "--at", "x"],
               capsys) == 2
    assert "--at: expected numbers" in capsys.readouterr().err
