"""Ensembles and the time-varying IRF estimators: ensemble_irf, sds, guarin; kbr/skirt ensemble mode."""
import numpy as np
import pytest

from jointbench import estimators
from jointbench.estimators import ensemble_irf
from jointbench.estimators._tvirf import mdl_solve
from jointbench.estimators.guarin import GuarinEstimate, time_basis
from jointbench.core.ensemble import Ensemble, data_kind, valid_mask
from jointbench.core.errors import InputError
from jointbench.core.estimate import IRFEstimate
from jointbench.core.estimate_tv import TVIRFEstimate
from jointbench.core.types import Trial, Truth
from tests.multisine_data import multisine_impedance_trial

FS = 100.0
LAGS = np.arange(-4, 5)               # +-40 ms at 100 Hz: the IRF of van de Ruit et al. (2018), Sec. V-E


def true_irf(seed: int = 1) -> np.ndarray:
    return np.random.default_rng(seed).standard_normal(len(LAGS))


def ensemble_of(H: np.ndarray, n: int, R: int, seed: int = 2, offset: float = 0.0, same_input: bool = False,
                noise: float = 0.0) -> Ensemble:
    """White inputs through a (time-varying, lags x time, or constant) IRF; outputs exact unless ``noise``."""
    rng = np.random.default_rng(seed)
    H = np.tile(H[:, None], (1, n)) if H.ndim == 1 else H
    tv = TVIRFEstimate(LAGS, H, FS, np.arange(n) / FS, np.ones(n, bool))
    U = rng.standard_normal((n, 1 if same_input else R)) * np.ones((1, R)) + offset
    Y = np.column_stack([tv.predict(U[:, r]) for r in range(R)])
    Y = Y + noise * Y.std() * rng.standard_normal(Y.shape) + offset
    return Ensemble.from_arrays(U, Y, FS, name="test")


def rel_err(est: TVIRFEstimate, H: np.ndarray) -> float:
    H = np.tile(H[:, None], (1, len(est.time))) if H.ndim == 1 else H
    v = est.valid
    return float(np.abs(est.h[:, v] - H[:, v]).max() / np.abs(H).max())


# ------------------------------------------------------------------------------------------ Ensemble
def test_ensemble_validation_names_the_realizations():
    a = Trial.from_arrays(np.arange(10.0), np.ones(10), FS, name="a")
    with pytest.raises(InputError, match="realization 'b' has 9 samples and 'a' 10"):
        Ensemble((a, Trial.from_arrays(np.arange(9.0), np.ones(9), FS, name="b")))
    with pytest.raises(InputError, match="'c' is sampled at 50 Hz and 'a' at 100 Hz"):
        Ensemble((a, Trial.from_arrays(np.arange(10.0), np.ones(10), 50.0, name="c")))
    with pytest.raises(InputError, match="imposes the torque"):
        Ensemble((a, Trial.from_arrays(np.arange(10.0), np.ones(10), FS, imposed="torque", name="d")))
    with pytest.raises(InputError, match="no realization"):
        Ensemble(())
    with pytest.raises(InputError, match="2-D"):
        Ensemble.from_arrays(np.ones(10), np.ones(10), FS)
    for msg in ("has 9 samples", "sampled at", "no realization"):
        assert "\n" not in msg


def test_ensemble_access_average_and_kinds():
    rng = np.random.default_rng(0)
    A, Y = rng.standard_normal((50, 3)), rng.standard_normal((50, 3))
    truths = [Truth(I=0.01, B=0.1, K=np.full(50, k), signals={"torque": Y[:, i]}) for i, k in enumerate((1, 2, 3))]
    ens = Ensemble(tuple(Trial.from_arrays(A[:, i], Y[:, i], FS, truth=truths[i], name=f"r{i}") for i in range(3)))
    assert (ens.size, ens.n, ens.fs) == (3, 50, FS)
    assert np.array_equal(ens.inputs, A) and np.array_equal(ens.outputs, Y)
    avg = ens.average()
    assert np.allclose(avg.angle, A.mean(axis=1)) and np.allclose(avg.torque, Y.mean(axis=1))
    assert np.allclose(avg.truth.K, 2.0) and np.allclose(avg.truth.signals["torque"], Y.mean(axis=1))
    assert ens.subset([0, 2]).size == 2 and ens.subset([0, 2])[1].name == "r2"
    assert data_kind(ens) == "ensemble" and data_kind(ens[0]) == "trial" and data_kind(list(ens)) == "pooled"


def test_ensemble_given_to_single_trial_estimators_is_one_line_error():
    ens = ensemble_of(true_irf(), 500, 12)
    for name in ("irf2_ls", "irf2_corr", "spectral", "fsewls", "ibk_irf"):
        with pytest.raises(InputError) as info:
            estimators.make(name).fit(ens)
        msg = str(info.value)
        assert "not an ensemble ('test', 12 realizations)" in msg and name in msg and "\n" not in msg
    assert estimators.REGISTRY.get("irf2_ls").refuses(ens).startswith("irf2_ls: takes single trials or pooled")
    assert estimators.REGISTRY.get("sds").refuses(ens) is None
    with pytest.raises(InputError, match="takes ensembles, not a single trial"):
        estimators.make("ensemble_irf").fit(ens[0])
    with pytest.raises(InputError, match="one record at a time.*give them as an Ensemble"):
        estimators.make("kbr").fit(list(ens)[:2])


# --------------------------------------------------------------------------------------- TVIRFEstimate
def test_tvirf_estimate_matches_the_time_invariant_irf():
    h = true_irf()
    n = 300
    u = np.random.default_rng(3).standard_normal(n)
    tv = TVIRFEstimate(LAGS, np.tile(h[:, None], (1, n)), FS, np.arange(n) / FS, np.ones(n, bool))
    ti = IRFEstimate(LAGS, h, FS, np.arange(n) / FS)
    assert np.allclose(tv.predict(u), ti.predict(u), atol=1e-12)
    assert tv.stiffness(1.0) == pytest.approx(np.sum(h))            # Ts x sum of the density h fs
    f = np.array([0.5, 3.0, 20.0])
    assert np.allclose(tv.frequency_response(f, 1.0), ti.frequency_response(f))
    frame = tv.response_frame()
    assert list(frame.columns) == ["time", "lag", "lag_s", "h"] and len(frame) == n * len(LAGS)
    assert np.allclose(frame["lag_s"], frame["lag"] / FS)
    assert list(tv.to_frame().columns) == ["time", "stiffness", "valid"]
    with pytest.raises(ValueError, match="fitted time base"):
        tv.predict(u[:10])


def test_valid_mask_of_any_estimate():
    n = 20
    tv = TVIRFEstimate(LAGS, np.zeros((9, n)), FS, np.arange(n) / FS, np.arange(n) >= 5)
    assert valid_mask(tv).sum() == 15 and not valid_mask(tv, np.array([0.02]))[0] and valid_mask(tv, 0.1)
    ti = IRFEstimate(LAGS, np.zeros(9), FS, np.arange(n) / FS)
    assert valid_mask(ti).all()


# -------------------------------------------------------------------------------- recovery, no noise
@pytest.mark.parametrize("name,settings,offset", [
    ("ensemble_irf", {"remove_mean": "none"}, 0.0),
    ("ensemble_irf", {}, 0.3),                              # the ensemble mean removed (default)
    ("sds", {}, 0.3),                                       # each segment's mean removed (default)
    ("guarin", {"basis": "gaussian"}, 0.3),                 # each record's mean removed (default)
    ("guarin", {"basis": "bspline"}, 0.3),
    ("guarin", {"basis": "legendre", "n_basis": 8}, 0.3),
])
def test_recovers_time_invariant_irf_without_noise(name, settings, offset):
    h = true_irf()
    est = estimators.make(name, settings).fit(ensemble_of(h, 1000, 30, offset=offset))
    assert isinstance(est, TVIRFEstimate) and np.array_equal(est.lags, LAGS)
    assert rel_err(est, h) < 0.01, (name, settings, rel_err(est, h))


def test_ensemble_irf_follows_any_time_variation_sample_by_sample():
    n = 600
    g = 1.0 + 0.5 * np.sin(2 * np.pi * np.arange(n) / n) + (np.arange(n) > 300)       # smooth plus a step
    H = true_irf()[:, None] * g[None, :]
    est = estimators.make("ensemble_irf").fit(ensemble_of(H, n, 40))
    assert rel_err(est, H) < 1e-6
    assert est.valid.sum() == n - 8 and not est.valid[:4].any() and not est.valid[-4:].any()


def test_mdl_order_on_hand_made_normal_equations():
    """Two directions: the second weakly excited (eigenvalue 1e-4). MDL keeps it only when the output
    variance it explains beats the penalty (1 + d ln n / n) on the residual."""
    Phi = np.array([[[1.0, 0.0], [0.0, 1e-4]]] * 2)
    # time 0: the weak direction explains 1e-8 of an output variance of 1.01 (noise); time 1: 0.25
    phi = np.array([[1.0, 1e-6], [1.0, 5e-3]])
    yvar = np.array([1.01, 1.26])
    h, order = mdl_solve(Phi, phi, yvar, n_obs=20, solver="mdl", rcond=1e-10)
    assert list(order) == [1, 2]
    assert np.allclose(h[0], [1.0, 0.0]) and np.allclose(h[1], [1.0, 50.0])
    # by hand: MDL(1) = (1 + ln20/20) * 0.01 = 0.0115, MDL(2) = (1 + 2 ln20/20) * (0.01 - 1e-8) = 0.0130 at time 0
    h, order = mdl_solve(Phi, phi, yvar, n_obs=20, solver="full", rcond=1e-10)
    assert list(order) == [2, 2] and np.allclose(h[0], [1.0, 0.01])


def mdl_pinv_loop(ens: Ensemble, m: int = 4) -> tuple[np.ndarray, np.ndarray]:
    """Reference: at every time the SVD of the R x L lagged inputs (ensemble mean removed), the MDL order
    (Westwick & Kearney 1997) and the truncated pseudo-inverse, one time after another."""
    U = ens.inputs - ens.inputs.mean(axis=1, keepdims=True)
    Y = ens.outputs - ens.outputs.mean(axis=1, keepdims=True)
    R, L = ens.size, 2 * m + 1
    hs, orders = [], []
    for i in range(ens.n - L + 1):
        A = np.column_stack([U[i + L - 1 - j] for j in range(L)]) / np.sqrt(R)      # column j: lag j - m
        y = Y[i + m] / np.sqrt(R)
        _, sv, Vt = np.linalg.svd(A, full_matrices=False)
        gain = Vt @ (A.T @ y) / sv ** 2                   # coefficient on each right singular vector
        residual = y @ y - np.cumsum(gain ** 2 * sv ** 2)
        d = np.arange(1, L + 1)
        order = int(np.argmin((1 + d * np.log(R) / R) * residual)) + 1
        hs.append(Vt[:order].T @ gain[:order])
        orders.append(order)
    return np.array(hs).T, np.array(orders)


@pytest.mark.parametrize("data", ["narrow", "white"])
def test_ensemble_irf_is_the_mdl_pseudo_inverse_at_every_time(data, monkeypatch):
    """The batched solution equals the per-time SVD with its MDL order: where the order varies (few
    realizations of a narrow-band input) and where it is mostly full (white input)."""
    if data == "narrow":
        rng = np.random.default_rng(3)
        U = np.cumsum(rng.standard_normal((300, 14)), axis=0)
        Y = np.column_stack([IRFEstimate(LAGS, true_irf(), FS, np.arange(300) / FS).predict(U[:, r])
                             for r in range(14)])
        ens = Ensemble.from_arrays(U, Y + 0.2 * Y.std() * rng.standard_normal(Y.shape), FS)
    else:
        ens = ensemble_of(true_irf(), 200, 40, noise=0.05)
    orders = []
    solve = ensemble_irf.mdl_solve

    def recorded(*args):
        h, order = solve(*args)
        orders.append(order)
        return h, order
    monkeypatch.setattr(ensemble_irf, "mdl_solve", recorded)
    est = estimators.make("ensemble_irf").fit(ens)
    h, order = mdl_pinv_loop(ens)
    assert np.array_equal(orders[0], order) and len(set(order)) > (2 if data == "narrow" else 0)
    assert np.allclose(est.h[:, est.valid], h, rtol=1e-9, atol=1e-12 * np.abs(h).max())


def test_ensemble_irf_mdl_truncates_when_the_input_is_narrow_band():
    rng = np.random.default_rng(5)
    n, R = 400, 30
    h = true_irf()
    U = np.cumsum(np.cumsum(rng.standard_normal((n + 50, R)), axis=0), axis=0)[50:]   # twice integrated: narrow
    Y = np.column_stack([IRFEstimate(LAGS, h, FS, np.arange(n) / FS).predict(U[:, r]) for r in range(R)])
    Y += 0.05 * Y.std() * rng.standard_normal(Y.shape)
    est = estimators.make("ensemble_irf").fit(Ensemble.from_arrays(U, Y, FS))
    median = int(est.info["order"].split("median ")[1].rstrip(")"))
    assert 1 <= median < 9, est.info["order"]


def test_sds_no_lag_crosses_a_segment_boundary():
    """Changing every sample outside one window (in every trial) must leave that window's IRF unchanged."""
    h = true_irf()
    n, W, s0 = 1200, 100, 500
    ens = ensemble_of(h, n, 5, noise=0.3)
    U, Y = ens.inputs.copy(), ens.outputs.copy()
    outside = np.ones(n, bool)
    outside[s0:s0 + W] = False
    rng = np.random.default_rng(8)
    U[outside] = rng.standard_normal((outside.sum(), 5))
    Y[outside] = rng.standard_normal((outside.sum(), 5))
    changed = Ensemble.from_arrays(U, Y, FS)
    a, b = (estimators.make("sds").fit(e) for e in (ens, changed))
    c = s0 + W // 2
    assert np.allclose(a.h[:, c], b.h[:, c], rtol=1e-9, atol=1e-12)
    assert not np.allclose(a.h[:, c + 1], b.h[:, c + 1], rtol=1e-3)     # the next window sees a changed sample
    assert not np.allclose(a.h[:, c - 1], b.h[:, c - 1], rtol=1e-3)


def test_sds_step_and_window_time():
    est = estimators.make("sds", {"step": 0.25}).fit(ensemble_of(true_irf(), 1000, 5))
    assert est.info["windows"] == len(np.arange(0, 1000 - 100 + 1, 25))
    assert est.valid[50] and not est.valid[49] and est.valid[950] and not est.valid[951]   # windows at 0 ... 900


@pytest.mark.parametrize("basis", ["gaussian", "bspline"])
def test_guarin_tracks_a_stiffness_step_within_basis_resolution(basis):
    n, step_at = 3000, 1500
    g = np.where(np.arange(n) < step_at, 1.0, 1.5)
    h = np.abs(true_irf()) + 0.1
    H = h[:, None] * g[None, :]
    ens = ensemble_of(H, n, 8)
    true = H.sum(axis=0)
    height = true[-1] - true[0]

    def transition(M):
        est = estimators.make("guarin", {"basis": basis, "n_basis": M}).fit(ens)
        k = est.stiffness(est.time)
        spacing = (n - 1) / (M - 3)                    # samples between centres / knots
        frac = (k - true[0]) / height
        rise = np.flatnonzero(frac > 0.9)[0] - np.flatnonzero(frac > 0.1)[0]
        far = (np.abs(np.arange(n) - step_at) > 3 * spacing) & est.valid
        return rise, spacing, float(np.abs(k - true)[far].max() / height) if far.any() else np.nan

    rise, spacing, far_err = transition(61)
    assert rise <= 1.5 * spacing and far_err < 0.05, (rise, spacing, far_err)
    rise_coarse, spacing_coarse, _ = transition(9)         # a coarser basis cannot follow the step as fast
    assert rise_coarse > 2 * rise


def test_guarin_reflex_pathway_separates_intrinsic_and_reflex():
    rng = np.random.default_rng(4)
    n, R = 2500, 10
    h, hr = true_irf(), 0.5 * np.exp(-np.arange(10) / 3.0)
    U = np.cumsum(rng.standard_normal((n, R)), axis=0) * 0.01
    U -= U.mean(axis=0)
    # a delay beyond the intrinsic lags (the velocity's central difference reaches one sample less): the
    # linear part of the rectified velocity then falls outside the intrinsic IRF and both are identifiable
    truth = GuarinEstimate(LAGS, np.tile(h[:, None], (1, n)), FS, np.arange(n) / FS, np.ones(n, bool),
                           reflex_h=np.tile(hr[:, None], (1, n)), reflex_delay=6)
    Y = np.column_stack([truth.predict(U[:, r]) for r in range(R)])
    est = estimators.make("guarin", {"n_basis": 4, "basis": "bspline", "reflex": True, "reflex_delay": 0.06,
                                     "reflex_lags": 0.1, "remove_mean": "none"}).fit(Ensemble.from_arrays(U, Y, FS))
    v = est.valid
    assert np.abs(est.h[:, v] - h[:, None]).max() < 1e-6 * np.abs(h).max()
    assert np.abs(est.reflex_h[:, v] - hr[:, None]).max() < 1e-6
    assert np.allclose(est.predict(U[:, 0])[v], Y[v, 0], atol=1e-8)


def test_time_basis_shapes():
    for kind, M in (("gaussian", 21), ("bspline", 21), ("legendre", 6)):
        B = time_basis(kind, M, 500)
        assert B.shape == (500, M)
    assert np.allclose(time_basis("bspline", 10, 300).sum(axis=1), 1.0)     # partition of unity


# -------------------------------------------------------------------------------- bad input
def test_fewer_realizations_than_lags():
    with pytest.raises(InputError) as info:
        estimators.make("ensemble_irf").fit(ensemble_of(true_irf(), 300, 5))
    msg = str(info.value)
    assert "5 realizations" in msg and "9 lags" in msg and "lag_before" in msg and "'pool'" in msg
    est = estimators.make("ensemble_irf", {"pool": 0.02}).fit(ensemble_of(true_irf(), 300, 5))   # 5 x 5 >= 9
    assert est.info["equations_per_time"] == 25


def test_window_shorter_than_lag_range():
    with pytest.raises(InputError, match=r"window = 0.05 s \(5 samples at 100 Hz\) is shorter than the lag range"):
        estimators.make("sds", {"window": 0.05}).fit(ensemble_of(true_irf(), 300, 5))
    with pytest.raises(InputError, match="longer than the records"):
        estimators.make("sds", {"window": 10.0}).fit(ensemble_of(true_irf(), 300, 5))


def test_basis_larger_than_the_data_supports():
    ens = ensemble_of(true_irf(), 300, 2)
    with pytest.raises(InputError, match="n_basis = 100 .* unknowns but only 2 x 292 = 584 equations"):
        estimators.make("guarin", {"n_basis": 100}).fit(ens)
    with pytest.raises(InputError, match="finer than two samples"):
        estimators.make("guarin", {"n_basis": 200}).fit(ens)


def test_same_input_in_every_realization_with_ensemble_mean_removal():
    ens = ensemble_of(true_irf(), 300, 12, same_input=True)
    with pytest.raises(InputError, match="same in every realization.*remove_mean = 'record'"):
        estimators.make("ensemble_irf").fit(ens)
    est = estimators.make("guarin", {"basis": "bspline", "n_basis": 5}).fit(ens)   # one input suffices here
    assert rel_err(est, true_irf()) < 0.01


# --------------------------------------------------------------------------------- ensemble mode
@pytest.mark.parametrize("name", ["kbr", "skirt"])
def test_kbr_and_skirt_fit_the_ensemble_average(name):
    trials = [multisine_impedance_trial(0.003, 0.1, 5.0, fs=44.0, seed=1, name=f"t{i}") for i in range(3)]
    rng = np.random.default_rng(0)
    trials = [t.replace(torque=t.torque + 0.05 * t.torque.std() * rng.standard_normal(t.n)) for t in trials]
    ens = Ensemble(tuple(trials), name="three")
    a = estimators.make(name).fit(ens)
    b = estimators.make(name).fit(ens.average())
    assert np.allclose(a.stiffness(a.time), b.stiffness(b.time), rtol=1e-12)
