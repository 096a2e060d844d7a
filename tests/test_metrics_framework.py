"""The comparison framework's metrics (studies.md D) on hand-checkable inputs (rliable style)."""
import numpy as np
import pytest

from jointbench.benchmarks.metrics import (bias, random_error, rise_time, step_rise_time, steps, stiffness_vaf,
                                total_error)


def test_stiffness_vaf_counts_an_offset():
    k = np.array([1.0, -1.0, 1.0, -1.0])           # sum (k - mean)^2 = 4
    assert stiffness_vaf(k, k) == pytest.approx(100.0)
    assert stiffness_vaf(k, np.zeros(4)) == pytest.approx(0.0)
    assert stiffness_vaf(k, k + 0.5) == pytest.approx(100 * (1 - 4 * 0.25 / 4))   # 75: an offset is an error
    with pytest.raises(ValueError, match="constant"):
        stiffness_vaf(np.ones(3), np.zeros(3))


def test_bias_random_and_total_by_hand():
    k = np.array([10.0, 20.0])
    khats = np.array([[11.0, 19.0],      # errors +1, -1
                      [13.0, 21.0]])     # errors +3, +1
    b_rms, b_mean = bias(k, khats)       # bias(t) = (+2, 0)
    assert b_rms == pytest.approx(np.sqrt((4 + 0) / 2)) and b_mean == pytest.approx(1.0)
    # SD over realizations (ddof 1) at each t: (11, 13) -> sqrt(2); (19, 21) -> sqrt(2)
    assert random_error(khats) == pytest.approx(np.sqrt(2.0))
    assert total_error(k, khats) == pytest.approx(np.sqrt((1 + 1 + 9 + 1) / 4))


@pytest.mark.parametrize("R", [2, 3, 10])
def test_total_error_identity(R):
    """total^2 = bias_rms^2 + random^2 (R - 1) / R, for any estimates."""
    rng = np.random.default_rng(R)
    k = 5 + np.sign(np.sin(np.linspace(0, 12, 300)))
    khats = k + rng.normal(0.3, 0.7, (R, 300)) + rng.normal(0, 0.2, 300)
    b_rms, _ = bias(k, khats)
    assert total_error(k, khats) ** 2 == pytest.approx(b_rms ** 2 + random_error(khats) ** 2 * (R - 1) / R,
                                                        rel=1e-12)


def test_random_error_needs_two_realizations_and_shapes_must_agree():
    with pytest.raises(ValueError, match="2 realizations"):
        random_error(np.ones((1, 5)))
    with pytest.raises(ValueError, match="need k"):
        bias(np.ones(4), np.ones((3, 5)))


def test_rise_time_of_a_ramp_is_eight_tenths_of_it():
    t = np.arange(0, 10, 0.01)
    m = np.clip((t - 4.0) / 2.0, 0, 1)           # a 2 s ramp from 0 to 1
    assert step_rise_time(t, m) == pytest.approx(1.6, abs=1e-9)
    assert step_rise_time(t, 0.5 * m) == float("inf")          # never reaches 90 %
    assert step_rise_time(t, 0.2 + 0.8 * m) == float("inf")    # never below 10 % before it


def test_rise_time_of_a_square_wave_averages_rising_and_falling_steps():
    fs = 100.0
    t = np.arange(0, 40, 1 / fs)
    k = 5 + 0.9 * np.sign(np.sin(2 * np.pi * t / 10 + 1e-9))    # steps at 5, 10, 15 ... 35 s
    assert len(steps(k)) == 7
    rise, n = rise_time(t, k, k)
    assert n == 7 and rise == pytest.approx(0.8 / fs)            # the truth itself: 0.8 of a sample
    # a first-order lag of time constant tau rises 10-90 % in tau ln 9
    tau = 0.2
    khat = np.empty_like(k)
    khat[0] = k[0]
    a = np.exp(-1 / (fs * tau))
    for i in range(1, len(k)):
        khat[i] = a * khat[i - 1] + (1 - a) * k[i]
    rise, _ = rise_time(t, k, khat)
    assert rise == pytest.approx(tau * np.log(9), rel=0.03)
    assert np.isnan(rise_time(t, np.full_like(t, 5.0), khat)[0])   # no step, no rise time
