"""The compiled eigensolver of the ensemble IRF estimators (estimators/_small_eigh.py) against
numpy.linalg.eigh, and the pseudo-inverse of ``mdl_solve`` against the numpy form it replaced."""
import sys
from pathlib import Path

import numpy as np
import pytest

from jointbench import estimators
from jointbench.core.ensemble import Ensemble
from jointbench.core.estimate_tv import TVIRFEstimate
from jointbench.estimators import _small_eigh, ensemble_irf, sds
from jointbench.estimators._small_eigh import eigh_descending, lagged_gram
from jointbench.estimators._tvirf import gram_stack, lagged, mdl_solve

sys.path.insert(0, str(Path(__file__).parent / "benchmarks"))
from test_bench_ensemble import tv_ensemble  # noqa: E402 - the benchmark's own ensemble

FS = 100.0


def check_decomposition(A: np.ndarray, s: np.ndarray, V: np.ndarray, tol: float = 1e-13) -> None:
    """Eigenvalues descending and equal to numpy's, V orthonormal, V diag(s) V^T = A (relative to |A|)."""
    scale = max(np.abs(A).max(), 1e-300)
    n = A.shape[-1]
    assert np.all(np.diff(s, axis=-1) <= 0)
    assert np.abs(s - np.linalg.eigvalsh(A)[..., ::-1]).max() <= tol * scale
    assert np.abs(np.swapaxes(V, -1, -2) @ V - np.eye(n)).max() <= tol * n
    assert np.abs(V @ (s[..., :, None] * np.swapaxes(V, -1, -2)) - A).max() <= tol * scale


@pytest.mark.parametrize("n", [1, 2, 3, 9, 21, 40])
def test_random_spd_stacks_match_numpy(n):
    # 37 matrices: a stack that is not a whole number of the solver's groups of B
    rng = np.random.default_rng(n)
    X = rng.standard_normal((37, n + 3, n))
    A = np.swapaxes(X, 1, 2) @ X / (n + 3)
    s, V = eigh_descending(A)
    assert s.shape == (37, n) and V.shape == (37, n, n)
    check_decomposition(A, s, V)


def test_two_by_two_by_hand():
    """[[2, 1], [1, 2]]: eigenvalues 3 and 1, eigenvectors (1, 1)/sqrt2 and (1, -1)/sqrt2 (up to sign)."""
    s, V = eigh_descending(np.array([[[2.0, 1.0], [1.0, 2.0]]]))
    assert np.allclose(s[0], [3.0, 1.0], rtol=0, atol=1e-15)
    assert np.allclose(np.abs(V[0]), np.sqrt(0.5), rtol=0, atol=1e-15)
    assert V[0, 0, 1] * V[0, 1, 1] < 0 < V[0, 0, 0] * V[0, 1, 0]


def test_diagonal_matrices_are_sorted_exactly():
    """Already diagonal: the eigenvalues are the diagonal, sorted, and V a signed permutation, exactly."""
    diag = np.array([[3.0, -1.0, 7.0, 0.0, 2.5], [1.0, 1.0, 1.0, 1.0, 1.0]])
    A = np.array([np.diag(d) for d in diag])
    s, V = eigh_descending(A)
    assert np.array_equal(s, -np.sort(-diag, axis=1))
    assert np.array_equal(np.abs(V[0]), np.eye(5)[:, [2, 0, 4, 3, 1]])
    check_decomposition(A, s, V, tol=0)


def test_repeated_eigenvalues():
    """Q diag(4, 4, 4, 1, 1, 0.5, 0.5, 0.5, 0.5) Q^T with a random rotation Q: each repeated eigenvalue is
    found to rounding and its eigenvectors span an orthonormal basis of the eigenspace."""
    rng = np.random.default_rng(7)
    lam = np.array([4.0, 4.0, 4.0, 1.0, 1.0, 0.5, 0.5, 0.5, 0.5])
    Q = np.linalg.qr(rng.standard_normal((5, 9, 9)))[0]
    A = Q @ (lam[:, None] * np.swapaxes(Q, 1, 2))
    s, V = eigh_descending(A)
    assert np.abs(s - lam).max() < 1e-14
    check_decomposition(A, s, V)
    top = V[:, :, :3]                                   # the eigenspace of 4: the projector matches
    assert np.abs(top @ np.swapaxes(top, 1, 2) - Q[:, :, :3] @ np.swapaxes(Q[:, :, :3], 1, 2)).max() < 1e-13


def test_rank_deficient_and_all_zero():
    """Gram matrices of 3 vectors in 9 dimensions (rank 3: six eigenvalues at rounding level), and the
    zero matrix (every eigenvalue 0, V orthonormal)."""
    rng = np.random.default_rng(3)
    X = rng.standard_normal((10, 3, 9))
    A = np.swapaxes(X, 1, 2) @ X
    s, V = eigh_descending(A)
    check_decomposition(A, s, V)
    assert np.all(s[:, :3] > 0.1) and np.abs(s[:, 3:]).max() < 1e-13 * s[:, 0].min()
    for n in (1, 2, 9):
        s, V = eigh_descending(np.zeros((2, n, n)))
        assert np.array_equal(s, np.zeros((2, n)))
        check_decomposition(np.zeros((2, n, n)), s, V, tol=0)


def test_scale_does_not_matter():
    """The solver scales each matrix by a power of two: a matrix times 2^-600 or 2^600 (whose squares
    would underflow or overflow) gives the same decomposition, eigenvalues times the factor, exactly."""
    rng = np.random.default_rng(11)
    X = rng.standard_normal((4, 12, 9))
    A = np.swapaxes(X, 1, 2) @ X
    s, V = eigh_descending(A)
    for f in (2.0 ** -600, 2.0 ** 600):
        sf, Vf = eigh_descending(A * f)
        assert np.array_equal(sf, s * f) and np.array_equal(Vf, V)


def test_non_finite_input_is_refused():
    A = np.eye(9)[None].repeat(40, axis=0)
    A[33, 2, 4] = A[33, 4, 2] = np.nan
    with pytest.raises(np.linalg.LinAlgError, match="matrix 33"):
        eigh_descending(A)


# --------------------------------------------------------------------------- mdl_solve vs the numpy form
def mdl_solve_numpy(Phi, phi, yvar, n_obs, solver, rcond):
    """The form mdl_solve had before the compiled solver (numpy.linalg.eigh), with its MDL values."""
    s, V = np.linalg.eigh(Phi)
    s, V = s[:, ::-1], V[:, :, ::-1]
    keep = s > rcond * s[:, :1]
    proj = np.einsum("tli,tl->ti", V, phi)
    inv = np.where(keep, 1.0 / np.where(keep, s, 1.0), 0.0)
    d = np.arange(1, Phi.shape[1] + 1)
    if solver == "full":
        order, coef, mdl = keep.sum(axis=1), proj * inv, None
    else:
        explained = np.cumsum(proj ** 2 * inv, axis=1)
        mdl = np.where(keep, (1.0 + d * np.log(n_obs) / n_obs) * (yvar[:, None] - explained), np.inf)
        order = np.argmin(mdl, axis=1) + 1
        coef = np.where(d[None, :] <= order[:, None], proj * inv, 0.0)
    return np.einsum("tli,ti->tl", V, coef), order, mdl


def compare(args: tuple, solver: str) -> tuple[np.ndarray, np.ndarray, int]:
    """Both forms on one stack: per time, the relative difference of h (to max |h(t)|) and the condition
    number of the directions kept (largest eigenvalue over the smallest kept); and the number of times
    whose orders differ. An order may differ only where the two MDL values are tied to rounding (h then
    differs by the direction dropped, and is not compared)."""
    Phi, phi, yvar, n_obs = args
    h, order = mdl_solve(Phi, phi, yvar, n_obs, solver, 1e-10)
    h0, order0, mdl = mdl_solve_numpy(Phi, phi, yvar, n_obs, solver, 1e-10)
    differ = np.flatnonzero(order != order0)
    for t in differ:
        a, b = mdl[t, order[t] - 1], mdl[t, order0[t] - 1]
        assert solver == "mdl" and abs(a - b) <= 1e-12 * abs(b), (t, order[t], order0[t], a, b)
    same = order == order0
    s = np.linalg.eigvalsh(Phi[same])[:, ::-1]
    cond = s[:, 0] / s[np.arange(len(s)), order0[same] - 1]
    rel = np.abs(h - h0)[same].max(axis=1) / np.abs(h0)[same].max(axis=1)
    return rel, cond, len(differ)


def check_agreement(args: tuple, solver: str) -> float:
    """The orders agree; h agrees within 1e-10 where the kept directions have a condition number up to
    1e4, and within 100 eps cond elsewhere (a backward-stable solver's h moves by about eps cond: numpy's
    and this one differ from an extended-precision answer by as much, see the test below). The largest
    relative difference."""
    rel, cond, differ = compare(args, solver)
    assert differ == 0
    good = cond <= 1e4
    assert rel[good].max(initial=0) < 1e-10, rel[good].max()
    assert np.all(rel <= 100 * np.finfo(float).eps * cond), (rel / (np.finfo(float).eps * cond)).max()
    return float(rel.max())


def recorded_stacks(monkeypatch, module, fit) -> list[tuple]:
    """The normal equations ``(Phi, phi, yvar, n_obs)`` an estimator hands mdl_solve during ``fit()``."""
    stacks = []

    def record(Phi, phi, yvar, n_obs, solver, rcond):
        stacks.append((Phi.copy(), phi.copy(), yvar.copy(), n_obs))
        return mdl_solve(Phi, phi, yvar, n_obs, solver, rcond)
    monkeypatch.setattr(module, "mdl_solve", record)
    fit()
    monkeypatch.undo()
    return stacks


def table2_like(seed: int, shared: bool) -> Ensemble:
    """Five 20 s records at 100 Hz, as in van de Ruit et al. (2018) Table II: one multisine (0.1 ... 19.3 Hz
    every 0.8 Hz, random phases) in every record (``shared``) or a new one in each, through a two-sided
    IRF whose gain follows a 20 s cycle, output noise 30% of its std."""
    rng = np.random.default_rng(seed)
    n, R = 2000, 5
    t = np.arange(n) / FS
    lines = np.arange(0.1, 19.31, 0.8)
    phases = rng.uniform(0, 2 * np.pi, (1 if shared else R, len(lines)))
    U = np.cos(2 * np.pi * t[:, None, None] * lines + phases[None]).sum(axis=-1) * np.ones((1, R))
    h = np.array([0.3, -0.8, 1.5, -4.0, 20.0, 4.0, 2.0, 1.0, 0.5])
    H = h[:, None] * (1.0 + 0.5 * np.sin(2 * np.pi * t / 20.0))[None, :]
    tv = TVIRFEstimate(np.arange(-4, 5), H, FS, t, np.ones(n, bool))
    Y = np.column_stack([tv.predict(U[:, r]) for r in range(R)])
    return Ensemble.from_arrays(U, Y + 0.3 * Y.std() * rng.standard_normal(Y.shape), FS)


@pytest.mark.parametrize("solver", ["mdl", "full"])
def test_mdl_solve_matches_numpy_on_the_benchmark_ensemble(solver, monkeypatch):
    """1000 samples x 50 realizations x 9 lags (tests/benchmarks/test_bench_ensemble.py)."""
    ens, _ = tv_ensemble(1000, 50, seed=1992)
    fit = estimators.make("ensemble_irf", {"solver": solver}).fit
    (args,) = recorded_stacks(monkeypatch, ensemble_irf, lambda: fit(ens))
    rel, cond, differ = compare(args, solver)
    assert differ == 0 and rel.max() < 1e-10 and cond.max() < 100, (differ, rel.max(), cond.max())


@pytest.mark.parametrize("shared", [True, False])
def test_mdl_solve_matches_numpy_on_table2_like_ensembles(shared, monkeypatch):
    """Table II's ensemble settings: ensemble_irf with pool 0.1 s and each record's mean removed, SDS with
    1 s windows; with one multisine shared by the five records, the pooled equations are few and alike
    and the MDL keeps fewer directions than lags at some times."""
    ens = table2_like(5, shared)
    irf = estimators.make("ensemble_irf", {"pool": 0.1, "remove_mean": "record"})
    stacks = recorded_stacks(monkeypatch, ensemble_irf, lambda: irf.fit(ens))
    stacks += recorded_stacks(monkeypatch, sds, lambda: estimators.make("sds", {"window": 1.0}).fit(ens))
    for args in stacks:
        check_agreement(args, "mdl")
    orders = np.concatenate([mdl_solve(*args, "mdl", 1e-10)[1] for args in stacks])
    assert orders.min() < 9 and (orders == 9).any()


def test_as_accurate_as_numpy_where_ill_conditioned(monkeypatch):
    """Where the MDL keeps all 9 directions of a badly conditioned Table II-like system (the shared
    multisine: condition numbers up to about 1e9), both solutions are compared with the exact solve
    refined in extended precision: each is off by up to a few eps times the condition number (the
    rounding of a backward-stable solver), and the compiled one by no more than that bound allows numpy's."""
    ens = table2_like(5, True)
    irf = estimators.make("ensemble_irf", {"pool": 0.1, "remove_mean": "record"})
    ((Phi, phi, yvar, n_obs),) = recorded_stacks(monkeypatch, ensemble_irf, lambda: irf.fit(ens))
    h, order = mdl_solve(Phi, phi, yvar, n_obs, "mdl", 1e-10)
    h0 = mdl_solve_numpy(Phi, phi, yvar, n_obs, "mdl", 1e-10)[0]
    full = np.flatnonzero(order == 9)
    assert len(full) >= 3
    x = np.linalg.solve(Phi[full], phi[full][..., None])[..., 0].astype(np.longdouble)
    for _ in range(6):                                  # residual in long double, correction in double
        r = phi[full].astype(np.longdouble) - np.einsum("tij,tj->ti", Phi[full].astype(np.longdouble), x)
        x += np.linalg.solve(Phi[full], r.astype(float)[..., None])[..., 0]
    ref = x.astype(float)
    s = np.linalg.eigvalsh(Phi[full])
    bound = 10 * np.finfo(float).eps * s[:, -1] / s[:, 0]
    err = np.abs(h[full] - ref).max(axis=1) / np.abs(ref).max(axis=1)
    err0 = np.abs(h0[full] - ref).max(axis=1) / np.abs(ref).max(axis=1)
    assert err0.max() > 1e-9 and bound.max() > 1e-7     # the case is the ill-conditioned one meant
    assert np.all(err <= bound) and np.all(err0 <= bound), (err / bound, err0 / bound)


def test_the_solver_groups_matrices_in_lanes():
    """The stack is cut into groups of B lanes: the stacks above and below one group give the same
    per-matrix answers as each matrix alone (no lane leaks into another)."""
    rng = np.random.default_rng(2)
    X = rng.standard_normal((_small_eigh.B + 3, 12, 9))
    A = np.swapaxes(X, 1, 2) @ X
    s, V = eigh_descending(A)
    for t in (0, _small_eigh.B - 1, _small_eigh.B, _small_eigh.B + 2):
        s1, V1 = eigh_descending(A[t:t + 1])
        assert np.array_equal(s1[0], s[t]) and np.array_equal(V1[0], V[t])


def test_lagged_gram_by_hand_and_against_the_products_of_lagged():
    """U = [1, 2, 3, 4] (one realization), 2 lags: X[i] = [u(i+1), u(i)], so Phi[0] = [[4, 2], [2, 1]],
    Phi[1] = [[9, 6], [6, 4]], Phi[2] = [[16, 12], [12, 9]]; and gram_stack(lagged(U, M1, M2)) for
    several lag ranges on a random ensemble (to rounding: the sums run in another order)."""
    Phi = lagged_gram(np.array([[1.0], [2.0], [3.0], [4.0]]), 2)
    assert np.array_equal(Phi, [[[4, 2], [2, 1]], [[9, 6], [6, 4]], [[16, 12], [12, 9]]])
    U = np.random.default_rng(4).standard_normal((300, 7))
    for m1, m2 in [(0, 0), (0, 4), (4, 4), (2, 7)]:
        want = gram_stack(lagged(U, m1, m2))
        assert np.allclose(lagged_gram(U, m1 + m2 + 1), want, rtol=0, atol=1e-14 * np.abs(want).max())
