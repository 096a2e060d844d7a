"""The Kronecker normal equations of the basis-function TV-IRF (``guarin``, ``tv_parallel_cascade``) against
their definition, term by term (hand-checkable: small sizes, explicit sums)."""
import numpy as np
import pytest

from jointbench.estimators._tvirf import _symmetric_gather, basis_normal


@pytest.mark.parametrize("T, R, L, M", [(1, 1, 1, 1), (7, 3, 2, 3), (50, 5, 9, 4), (40, 2, 3, 21)])
def test_basis_normal_is_the_sum_of_kronecker_products(T, R, L, M):
    rng = np.random.default_rng(T + 10 * L + 100 * M)
    X, Y, Phi = rng.standard_normal((T, R, L)), rng.standard_normal((T, R)), rng.standard_normal((T, M))
    G, b = basis_normal(X, Y, Phi)
    # definition: G = sum_t (phi phi^T) (x) (X^T X), b = sum_t phi (x) X^T y, unknowns ordered (m, l)
    G_def = sum(np.kron(np.outer(Phi[t], Phi[t]), X[t].T @ X[t]) for t in range(T))
    b_def = sum(np.kron(Phi[t], X[t].T @ Y[t]) for t in range(T))
    assert G.shape == (M * L, M * L) and b.shape == (M * L,)
    np.testing.assert_allclose(G, G_def, rtol=1e-12, atol=1e-12 * np.abs(G_def).max())
    np.testing.assert_allclose(b, b_def, rtol=1e-12, atol=1e-12 * np.abs(b_def).max())
    assert np.array_equal(G, G.T)                  # gathered from one product per pair: exactly symmetric


def test_symmetric_gather_by_hand():
    # M = 2 basis functions (pairs 00, 01, 11 -> 0, 1, 2), L = 2 lags (pairs 00, 01, 11 -> 0, 1, 2);
    # G[(m, l), (m', l')] = P[pair(m, m'), pair(l, l')] in a 3 x 3 product, flattened row by row
    idx = _symmetric_gather(2, 2)
    assert idx.tolist() == [[0, 1, 3, 4],
                            [1, 2, 4, 5],
                            [3, 4, 6, 7],
                            [4, 5, 7, 8]]
    assert not idx.flags.writeable
