"""``jointbench estimate`` on ensembles: 2-D NPZ/.mat files, several records, outputs and one-line errors."""
import numpy as np
import pandas as pd
import pytest
from scipy import io as sio

from jointbench import estimators
from jointbench.fitting import read_ensemble
from jointbench.core.ensemble import Ensemble
from jointbench.core.errors import InputError
from jointbench.core.estimate_tv import TVIRFEstimate
from tests.test_cli_estimate import cli

FS = 100.0
LAGS = np.arange(-4, 5)


def ensemble_arrays(n=1500, R=12, seed=0, gain=None):
    """White inputs through a two-sided IRF whose gain ramps over the record (stiffness 40 ... 60)."""
    rng = np.random.default_rng(seed)
    h = np.array([0.5, -1.0, 2.0, -6.0, 40.0, 6.0, 4.0, 2.0, 2.5])          # sums to 50
    g = np.linspace(0.8, 1.2, n) if gain is None else gain
    tv = TVIRFEstimate(LAGS, h[:, None] * g[None, :], FS, np.arange(n) / FS, np.ones(n, bool))
    U = 0.01 * rng.standard_normal((n, R))
    Y = np.column_stack([tv.predict(U[:, r]) for r in range(R)])
    return U, Y, 50 * g


def one_line_error(capsys, *parts):
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and err.startswith("jointbench: error:"), err
    for p in parts:
        assert p in err, (p, err)
    return err


def test_npz_ensemble_gives_stiffness_and_long_irf(tmp_path, capsys):
    U, Y, k = ensemble_arrays()
    np.savez(tmp_path / "ens.npz", angle=U, torque=Y, fs=FS)
    out = tmp_path / "o.csv"
    assert cli(["-e", "ensemble_irf", "-i", tmp_path / "ens.npz", "-o", out]) == 0
    frame = pd.read_csv(out)
    assert list(frame.columns) == ["time", "stiffness", "stiffness_lo", "stiffness_hi", "valid"] and len(frame) == 1500
    v = frame["valid"].to_numpy()
    assert np.allclose(frame["stiffness"][v], k[v], rtol=1e-6)
    irf = pd.read_csv(tmp_path / "o_irf.csv")
    assert list(irf.columns) == ["time", "lag", "lag_s", "h"] and len(irf) == 1500 * 9
    assert np.allclose(irf["lag_s"], irf["lag"] / FS)
    text = capsys.readouterr().out
    assert "ens.npz[0]" in text and "ens.npz[11]" in text and "VAF of the predicted torque" in text
    assert "where the time-varying IRF is estimated" in text


def test_mat_ensemble_with_time(tmp_path, capsys):
    U, Y, k = ensemble_arrays(n=1200, R=5)
    t = 3.0 + np.arange(1200) / FS
    sio.savemat(tmp_path / "ens.mat", {"angle": U, "torque": Y, "time": t[:, None]})
    out = tmp_path / "o.csv"
    assert cli(["-e", "sds", "-i", tmp_path / "ens.mat", "-o", out]) == 0
    frame = pd.read_csv(out)
    assert frame["time"].iloc[0] == pytest.approx(3.0)
    v = frame["valid"].to_numpy()
    assert np.allclose(frame["stiffness"][v], k[v], rtol=0.02)     # SDS: constant over each 1 s window


def test_several_records_become_an_ensemble(tmp_path, capsys):
    U, Y, k = ensemble_arrays(n=1200, R=10)
    paths = []
    for r in range(10):
        p = tmp_path / f"r{r}.csv"
        pd.DataFrame({"time": np.arange(1200) / FS, "angle": U[:, r], "torque": Y[:, r]}).to_csv(p, index=False)
        paths += ["-i", p]
    out = tmp_path / "o.csv"
    assert cli(["-e", "ensemble_irf", *paths, "-o", out]) == 0          # ensemble-only: automatic
    v = pd.read_csv(out)["valid"].to_numpy()
    assert np.allclose(pd.read_csv(out)["stiffness"][v], k[v], rtol=1e-6)
    assert cli(["-e", "guarin", *paths, "--ensemble", "--set", "n_basis=8", "-o", tmp_path / "g.csv"]) == 0
    g = pd.read_csv(tmp_path / "g.csv")
    assert np.allclose(g["stiffness"][g["valid"]], k[g["valid"].to_numpy()], rtol=0.01)


def test_read_records_kinds(tmp_path):
    U, Y, _ = ensemble_arrays(n=300, R=3)
    np.savez(tmp_path / "ens.npz", angle=U, torque=Y, fs=FS)
    np.savez(tmp_path / "one.npz", angle=U[:, 0], torque=Y[:, 0], fs=FS)
    assert read_ensemble.is_ensemble_file(tmp_path / "ens.npz")
    assert not read_ensemble.is_ensemble_file(tmp_path / "one.npz")
    ens = read_ensemble.read_records([tmp_path / "ens.npz"])
    assert isinstance(ens, Ensemble) and ens.size == 3 and ens.fs == FS
    trials = read_ensemble.read_records([tmp_path / "one.npz", tmp_path / "one.npz"])
    assert isinstance(trials, list) and len(trials) == 2


def test_one_rule_decides_whether_records_are_an_ensemble(tmp_path):
    """pipeline.ensemble_name, the one place (for api.fit and jointbench estimate alike): an Ensemble given is
    one unless ensemble=False; a list is one with ensemble=True, or by default when there are several and the
    estimator takes ensembles only."""
    from jointbench.fitting.pipeline import ensemble_name

    U, Y, _ = ensemble_arrays(n=300, R=3)
    ens = Ensemble.from_arrays(U, Y, FS, name="e")
    two = list(ens.realizations[:2])
    only_ensembles, pools = estimators.make("ensemble_irf"), estimators.make("irf2_ls")
    assert ensemble_name(pools, ens, None) == "e" and ensemble_name(pools, ens, False) is None
    assert ensemble_name(only_ensembles, two, None) == "2 records"
    assert ensemble_name(pools, two, None) is None and ensemble_name(pools, two, True) == "2 records"
    assert ensemble_name(only_ensembles, two[:1], None) is None
    assert ensemble_name(pools, two[:1], True) == two[0].name


@pytest.mark.parametrize("make,argv,parts", [
    (lambda d, U, Y: np.savez(d / "e.npz", angle=U.T, torque=Y.T, fs=FS), ["-e", "sds", "-i", "{d}/e.npz"],
     ["e.npz", "samples x realizations", "transpose"]),
    (lambda d, U, Y: np.savez(d / "e.npz", angle=U, torque=Y[:, :2], fs=FS), ["-e", "sds", "-i", "{d}/e.npz"],
     ["e.npz", "differ in shape"]),
    (lambda d, U, Y: np.savez(d / "e.npz", angle=U, torque=Y), ["-e", "sds", "-i", "{d}/e.npz"],
     ["e.npz", "no sampling rate", "--fs"]),
    (lambda d, U, Y: np.savez(d / "e.npz", angle=U, torque=Y, time=np.arange(U.shape[1]) / FS),
     ["-e", "sds", "-i", "{d}/e.npz"], ["e.npz", "'time' has 3 samples", "transpose"]),
    (lambda d, U, Y: np.savez(d / "e.npz", angle=U, torque=Y, fs=FS), ["-e", "irf2_ls", "-i", "{d}/e.npz"],
     ["irf2_ls", "not an ensemble", "e.npz"]),
    (lambda d, U, Y: np.savez(d / "e.npz", angle=U, torque=Y, fs=FS), ["-e", "ensemble_irf", "-i", "{d}/e.npz"],
     ["3 realizations", "9 lags", "'pool'"]),
    (lambda d, U, Y: np.savez(d / "e.npz", angle=U, torque=Y, fs=FS),
     ["-e", "sds", "-i", "{d}/e.npz", "--set", "window=50ms"], ["window = 0.05 s", "shorter than the lag range"]),
    (lambda d, U, Y: np.savez(d / "e.npz", angle=U, torque=Y, fs=FS),
     ["-e", "guarin", "-i", "{d}/e.npz", "--set", "n_basis=400"], ["n_basis = 400", "data cannot support"]),
    (lambda d, U, Y: np.savez(d / "e.npz", angle=U, torque=Y, fs=FS),
     ["-e", "sds", "-i", "{d}/e.npz", "-i", "{d}/e.npz"], ["e.npz", "only --input"]),
    (lambda d, U, Y: (np.savez(d / "a.npz", angle=U[:, 0], torque=Y[:, 0], fs=FS),
                      np.savez(d / "b.npz", angle=U[:-1, 1], torque=Y[:-1, 1], fs=FS)),
     ["-e", "guarin", "--ensemble", "-i", "{d}/a.npz", "-i", "{d}/b.npz"], ["'b.npz'", "299 samples", "same length"]),
    (lambda d, U, Y: (np.savez(d / "a.npz", angle=U[:, 0], torque=Y[:, 0], fs=FS),
                      np.savez(d / "b.npz", angle=U[:, 1], torque=Y[:, 1], fs=2 * FS)),
     ["-e", "guarin", "--ensemble", "-i", "{d}/a.npz", "-i", "{d}/b.npz"], ["different sampling rates", "b.npz"]),
])
def test_bad_ensemble_input_is_one_line_naming_file_or_option(tmp_path, capsys, make, argv, parts):
    U, Y, _ = ensemble_arrays(n=300, R=3)
    make(tmp_path, U, Y)
    argv = [a.format(d=tmp_path) for a in argv]
    assert cli([*argv, "-o", tmp_path / "o.csv"]) == 2
    one_line_error(capsys, *parts)
    assert not (tmp_path / "o.csv").exists()


def test_read_ensemble_nan_names_the_realization(tmp_path):
    U, Y, _ = ensemble_arrays(n=300, R=3)
    Y[10, 2] = np.nan
    np.savez(tmp_path / "e.npz", angle=U, torque=Y, fs=FS)
    with pytest.raises(InputError, match=r"e.npz: .*realization|e.npz\[2\]"):
        read_ensemble.read_ensemble(tmp_path / "e.npz")
