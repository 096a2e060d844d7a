import numpy as np
import pytest

from benchmarks.metrics import relative_error, rmse, vaf


def test_vaf_hand_values():
    y = np.array([1.0, -1.0, 1.0, -1.0])          # var 1
    assert vaf(y, y) == pytest.approx(100.0)
    assert vaf(y, np.zeros(4)) == pytest.approx(0.0)
    assert vaf(y, 0.5 * y) == pytest.approx(75.0)  # residual 0.5 y -> var 0.25
    assert vaf(y, y + 3.0) == pytest.approx(100.0)  # an offset is not variance


def test_vaf_rejects_bad_shapes_and_constant_reference():
    with pytest.raises(ValueError, match="shapes"):
        vaf(np.ones(3), np.ones(4))
    with pytest.raises(ValueError, match="zero variance"):
        vaf(np.ones(3), np.zeros(3))


def test_rmse_and_relative_error():
    assert rmse([0, 0, 0, 0], [1, -1, 1, -1]) == pytest.approx(1.0)
    assert rmse([1, 2], [1, 4]) == pytest.approx(np.sqrt(2.0))
    assert relative_error(50.0, 51.0) == pytest.approx(2.0)
    assert relative_error(-2.0, -1.0) == pytest.approx(-50.0)
