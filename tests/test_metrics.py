import numpy as np
import pytest

from jointbench.benchmarks.metrics import relative_error, rmse, vafm, vafv
from jointbench.core.scores import vaf


def test_vaf_hand_values():
    y = np.array([1.0, -1.0, 1.0, -1.0])          # var 1
    assert vaf(y, y) == pytest.approx(100.0)
    assert vaf(y, np.zeros(4)) == pytest.approx(0.0)
    assert vaf(y, 0.5 * y) == pytest.approx(75.0)  # residual 0.5 y -> var 0.25
    assert vaf(y, y + 3.0) == pytest.approx(100.0)  # an offset is not variance


def test_vaf_rejects_bad_shapes_and_constant_reference():
    with pytest.raises(ValueError, match="shape"):
        vaf(np.ones(3), np.ones(4))
    with pytest.raises(ValueError, match="does not vary"):
        vaf(np.ones(3), np.zeros(3))


def test_rmse_and_relative_error():
    assert rmse([0, 0, 0, 0], [1, -1, 1, -1]) == pytest.approx(1.0)
    assert rmse([1, 2], [1, 4]) == pytest.approx(np.sqrt(2.0))
    assert relative_error(50.0, 51.0) == pytest.approx(2.0)
    assert relative_error(-2.0, -1.0) == pytest.approx(-50.0)


# --- Xu & Hollerbach (1998) eq. 8 ---------------------------------------------------------------
def test_vafm_hand_values():
    x, xhat = [1.0, 2.0, 3.0], [1.0, 2.0, 4.0]      # means 2 and 7/3, mean(x^2) = 14/3 > 1
    assert vafm(x, xhat) == pytest.approx(100 * (1 - (1 / 9) / (14 / 3)))   # 97.619...
    assert vafm(x, [0.0, 1.0, 2.0]) == pytest.approx(100 * (1 - 1 / (14 / 3)))
    assert vafm(x, [3.0, 2.0, 1.0]) == pytest.approx(100.0)  # VAFM sees only the mean
    # mean(x^2) = 0.05 < 1: the denominator is set to 1 (paper's rule)
    assert vafm([0.1, 0.3], [0.2, 0.4]) == pytest.approx(100 * (1 - 0.01))
    assert vafm([0.0, 0.0], [0.5, 0.5]) == pytest.approx(75.0)


def test_vafv_hand_values_without_floor():
    x, xhat = [1.0, 2.0, 3.0], [1.0, 2.0, 4.0]      # x~ = [-1, 0, 1]; xhat~ = [-4/3, -1/3, 5/3]
    # sum (x~ - xhat~)^2 = 1/9 + 1/9 + 4/9 = 2/3; sum x~^2 = 2; dt = 1 s: integral 2 > 1, no floor
    assert vafv(x, xhat, dt=1.0) == pytest.approx(100 * (1 - (2 / 3) / 2))   # 66.67
    assert vafv(x, np.add(xhat, 10.0), dt=1.0) == pytest.approx(100 * (1 - (2 / 3) / 2))  # offsets ignored
    assert vafv(x, x, dt=0.5) == pytest.approx(100.0)
    y = 10 * np.array([1.0, -1.0, 1.0, -1.0])       # var 100: no floor in either reading
    assert vafv(y, 0.5 * y, dt=0.01) == pytest.approx(75.0)
    assert vafv(y, 0.5 * y) == pytest.approx(75.0)


def test_vafv_floor_on_the_time_integral_or_on_the_mean():
    x, xhat = [1.0, 2.0, 3.0], [1.0, 2.0, 4.0]
    # dt = 0.1 s: integral of x~^2 = 0.2 < 1 -> 1; numerator (2/3) * 0.1
    assert vafv(x, xhat, dt=0.1) == pytest.approx(100 * (1 - 0.2 / 3))      # 93.33
    # dt = None: mean(x~^2) = 2/3 < 1 -> 1; numerator mean = 2/9
    assert vafv(x, xhat) == pytest.approx(100 * (1 - 2 / 9))                # 77.78
    # a constant reference (e.g. the inertia): denominator 0 -> 1
    assert vafv([0.06] * 4, [0.05, 0.07, 0.05, 0.07], dt=1.0) == pytest.approx(100 * (1 - 4e-4))
    assert vafv([0.06] * 4, [0.05, 0.07, 0.05, 0.07]) == pytest.approx(100 * (1 - 1e-4))


def test_vafm_vafv_reject_bad_input():
    with pytest.raises(ValueError, match="shape"):
        vafm(np.ones(3), np.ones(4))
    with pytest.raises(ValueError, match="shape"):
        vafv(np.ones(3), np.ones(4), dt=1.0)
    with pytest.raises(ValueError, match="empty"):
        vafm([], [])
    with pytest.raises(ValueError, match="dt"):
        vafv([1.0, 2.0], [1.0, 2.0], dt=0.0)
