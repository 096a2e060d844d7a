"""Every registered time-variation profile: deterministic, exact minimum, positivity checked by the joints;
and the shapes added for comparison studies (ramp, smooth_random, file)."""
import hashlib

import numpy as np
import pytest

from jointbench.core.errors import ConfigError
from jointbench.sims import PROFILES, Experiment, simulate
from jointbench.sims.joint_time_varying import TimeVaryingJoint
from jointbench.sims.profile import parse_profile

T = np.linspace(-5.0, 130.0, 270_001)          # beyond one period of every case below, 0.5 ms apart


@pytest.fixture(scope="module")
def stiffness_csv(tmp_path_factory):
    p = tmp_path_factory.mktemp("profiles") / "k.csv"
    p.write_text("# recorded stiffness\ntime,value\n-10,40\n0,42.5\n30,55\n60,31\n140,40\n")
    return p


def cases(csv_path) -> dict:
    """One case per registered shape, all with minimum 25 (a new shape must be added here)."""
    return {
        "constant": 25.0,
        "sine": {"shape": "sine", "mean": 40, "amplitude": 15, "frequency": "0.5 Hz"},
        "square": {"shape": "square", "mean": 40, "amplitude": 15, "period": "20 s"},
        "piecewise": {"shape": "piecewise", "times": [0, 10, 20], "values": [40, 25, 55], "interpolate": "linear"},
        "ramp": {"shape": "ramp", "initial": 55, "final": 25, "start": "10 s", "duration": "20 s"},
        "smooth_random": {"shape": "smooth_random", "mean": 40, "amplitude": 15, "bandwidth": "0.5 Hz", "seed": 3},
        "file": {"shape": "file", "path": str(csv_path).replace("k.csv", "k25.csv")},
    }


@pytest.fixture(scope="module")
def profile_cases(stiffness_csv):
    (stiffness_csv.parent / "k25.csv").write_text("time,value\n-10,40\n0,25\n50,55\n140,40\n")
    return cases(stiffness_csv)


def test_every_registered_profile_has_a_case(profile_cases):
    assert set(profile_cases) == set(PROFILES.names())


@pytest.mark.parametrize("shape", sorted(PROFILES.names()))
def test_every_profile_is_deterministic_with_an_exact_minimum(profile_cases, shape):
    a, b = parse_profile(profile_cases[shape], "K"), parse_profile(profile_cases[shape], "K")
    assert a.shape == shape
    x = a.at(T)
    assert np.array_equal(x, b.at(T))                      # a function of its settings only
    assert a.minimum == 25.0
    assert x.min() >= a.minimum                           # never below the minimum it reports ...
    assert x.min() - a.minimum < 1e-6 * 15                # ... and reaches it (within 0.5 ms of its time)
    assert parse_profile(a, "K") is a


@pytest.mark.parametrize("shape", sorted(PROFILES.names()))
def test_joints_check_positivity_from_the_minimum(profile_cases, shape):
    """Each case lowered so that only part of it goes negative: the joint refuses it when the config is read."""
    data = profile_cases[shape]
    TimeVaryingJoint(I=0.06, K=data, damping_ratio=0.3)
    if shape == "file":
        neg = data["path"].replace("k25.csv", "kneg.csv")
        with open(neg, "w") as fh:
            fh.write("time,value\n0,40\n20,-5\n60,40\n")
    low = {"constant": lambda: -5.0, "sine": lambda: {**data, "mean": 10}, "square": lambda: {**data, "mean": 10},
           "piecewise": lambda: {**data, "values": [10, -5, 25]}, "ramp": lambda: {**data, "final": -5},
           "smooth_random": lambda: {**data, "mean": 10}, "file": lambda: {**data, "path": neg}}[shape]()
    with pytest.raises(ConfigError, match="'K'.*> 0"):
        TimeVaryingJoint(I=0.06, K=low, damping_ratio=0.3)


# ------------------------------------------------------------------------------------------------- ramp
def test_ramp_values():
    r = parse_profile({"shape": "ramp", "initial": 2, "final": 6, "start": 1, "duration": 2}, "x")
    assert list(r.at([0.0, 1.0, 1.5, 2.0, 3.0, 9.0])) == [2, 2, 3, 4, 6, 6]
    assert r.minimum == 2 and not r.constant
    down = parse_profile({"shape": "ramp", "initial": 6, "final": 2, "duration": "4 s"}, "x")
    assert list(down.at([-1.0, 0.0, 1.0, 4.0, 5.0])) == [6, 6, 5, 2, 2] and down.minimum == 2
    with pytest.raises(ConfigError, match="'duration'.*> 0"):
        parse_profile({"shape": "ramp", "initial": 6, "final": 2, "duration": 0}, "x")


# ---------------------------------------------------------------------------------------- smooth_random
def smooth(**kw):
    return parse_profile({"shape": "smooth_random", "mean": 0, "amplitude": 1, "bandwidth": "1 Hz",
                          "seed": 0, "period": "40 s", **kw}, "x")


def test_smooth_random_seeds_range_and_band():
    a, b = smooth(seed=1), smooth(seed=2)
    t = np.arange(40_000) / 1000.0                         # one period at 1 kHz
    xa = a.at(t)
    assert not np.allclose(xa, b.at(t))                    # another seed, another profile
    assert np.array_equal(xa, smooth(seed=1).at(t))
    assert np.allclose(a.at(t + 40.0), xa, rtol=0, atol=1e-12)                  # repeats with the period
    assert -1 <= xa.min() < -1 + 1e-5 and 1 - 1e-5 < xa.max() <= 1        # spans [-1, 1] exactly
    X = np.abs(np.fft.rfft(xa)) / len(t)
    f = np.fft.rfftfreq(len(t), 1e-3)
    assert X[f > 1.0 + 1e-9].max() < 1e-12 * X.max()      # band-limited: nothing above 1 Hz
    assert np.count_nonzero(X[(f > 0) & (f <= 1.0)] > 1e-6 * X.max()) >= 35   # 40 lines, Gaussian weights
    # smooth: the steepest slope is bounded by the band (Bernstein: |x'| <= 2 pi bandwidth max|x - mean|)
    assert np.abs(np.diff(xa)).max() * 1000 <= 2 * np.pi * 1.0 * 1.0 * 2


@pytest.mark.parametrize("data, words", [
    ({"bandwidth": "0.01 Hz"}, "below 1/period"),
    ({"seed": -1}, "'seed'"),
    ({"amplitude": -1}, "'amplitude'"),
    ({"bandwidth": "1 kHz", "period": "100 s"}, "lines, more than"),
])
def test_smooth_random_bad_settings(data, words):
    with pytest.raises(ConfigError, match=words):
        smooth(**data)


def test_smooth_random_needs_a_seed():
    with pytest.raises(ConfigError, match="missing required key 'seed'"):
        parse_profile({"shape": "smooth_random", "mean": 0, "amplitude": 1, "bandwidth": 1}, "x")


# ------------------------------------------------------------------------------------------------- file
def test_file_profile_csv_and_npy(tmp_path, stiffness_csv):
    csv = parse_profile({"shape": "file", "path": str(stiffness_csv)}, "K")
    assert np.allclose(csv.at([0.0, 15.0, 30.0, 45.0]), [42.5, 48.75, 55.0, 43.0])        # linear
    step = parse_profile({"shape": "file", "path": str(stiffness_csv), "interpolate": "step"}, "K")
    assert list(step.at([0.0, 15.0, 30.0, 45.0])) == [42.5, 42.5, 55.0, 55.0]
    assert csv.minimum == 31.0
    npy = tmp_path / "k.npy"
    np.save(npy, np.column_stack([csv.times, csv.values]))
    same = parse_profile({"shape": "file", "path": str(npy)}, "K")
    assert np.array_equal(same.at(T[(T >= -10) & (T <= 140)]), csv.at(T[(T >= -10) & (T <= 140)]))


def test_file_profile_outside_its_times(tmp_path):
    p = tmp_path / "short.csv"
    p.write_text("time,value\n0,5\n10,6\n")
    prof = parse_profile({"shape": "file", "path": str(p)}, "K")
    with pytest.raises(ConfigError, match=r"short.csv: asked for t = 12 s, outside the file's times 0 \.\.\. 10 s"):
        prof.at([0.0, 12.0])
    held = parse_profile({"shape": "file", "path": str(p), "outside": "hold"}, "K")
    assert list(held.at([-1.0, 12.0])) == [5.0, 6.0]


def test_file_profile_sha256(tmp_path):
    p = tmp_path / "k.csv"
    p.write_text("time,value\n0,5\n10,6\n")
    digest = hashlib.sha256(p.read_bytes()).hexdigest()
    assert parse_profile({"shape": "file", "path": str(p), "sha256": digest}, "K").minimum == 5
    with pytest.raises(ConfigError, match="k.csv: its SHA-256 is"):
        parse_profile({"shape": "file", "path": str(p), "sha256": "0" * 64}, "K")


@pytest.mark.parametrize("name, content, words", [
    ("missing.csv", None, "missing.csv: not found"),
    ("noheader.csv", "0,1\n1,2\n", "noheader.csv: line 1: expected the header 'time,value'"),
    ("fields.csv", "time,value\n0,1\n1,2,3\n", "fields.csv: line 3: expected 2 fields"),
    ("text.csv", "time,value\n0,1\n1,abc\n", "text.csv: line 3: not two numbers"),
    ("one.csv", "time,value\n0,1\n", "one.csv: needs at least 2 rows"),
    ("nan.csv", "time,value\n0,1\n1,nan\n", "nan.csv: row 2 of the data is not finite"),
    ("order.csv", "time,value\n0,1\n2,2\n1,3\n", "order.csv: times must increase strictly; data rows 2 and 3"),
    ("empty.csv", "", "empty.csv: empty"),
    ("k.txt", "time,value\n0,1\n1,2\n", "k.txt: unsupported type '.txt'"),
    ("shape.npy", np.zeros((4, 3)), r"shape.npy: expected a numeric array of shape \(n, 2\)"),
    ("bad.npy", "not an array", "bad.npy: not a readable .npy array"),
])
def test_file_profile_errors_name_the_file(tmp_path, name, content, words):
    p = tmp_path / name
    if isinstance(content, np.ndarray):
        np.save(p, content)
    elif content is not None:
        p.write_text(content)
    with pytest.raises(ConfigError, match=words):
        parse_profile({"shape": "file", "path": str(p)}, "K")


# ------------------------------------------------------------------------------------ in a simulation
@pytest.mark.parametrize("shape", ["ramp", "smooth_random", "file"])
def test_new_profiles_simulate_deterministically(profile_cases, shape):
    spec = {"joint": {"model": "time_varying", "I": 0.06, "damping_ratio": 0.3, "K": profile_cases[shape]},
            "apparatus": {"kind": "torque_drive"},
            "perturbation": {"kind": "prbs", "amplitude": 4, "clock": "10 ms"},
            "fs_sim": "2 kHz", "duration": "4 s", "acquisition": {"detrend": False, "fs": "500 Hz", "trim": "0.5 s"}}
    e = Experiment.from_mapping(spec, "test")
    a, b = simulate(e, 1), simulate(e, 1)
    assert np.array_equal(a.angle, b.angle) and np.array_equal(a.torque, b.torque)
    assert np.all(np.isfinite(a.angle))
