"""The one line-detection rule of the multisine estimators (estimators/_multisine_lines.py), and that
skirt and KBR both use it: same lines found, same inputs refused, whichever estimator asks."""
import numpy as np
import pytest

from jointbench import estimators
from jointbench.estimators._multisine_lines import MAX_LEAKAGE, excited_bins, multisine_bins
from jointbench.core.errors import InputError
from jointbench.core.types import Trial
from tests.test_skirt import FS, LINES, N, T, lti_trial


def kbr_lines(trial, **settings):
    return estimators.make("kbr", settings)._lines(trial)


def skirt_lines(trial, **settings):
    return estimators.make("skirt", settings)._lines([trial])


def test_both_estimators_find_the_study_lines():
    tr = lti_trial()
    want = np.rint(LINES * T).astype(int)
    assert np.array_equal(excited_bins("x", tr.input, FS, 20.0), want)
    assert np.array_equal(kbr_lines(tr), want) and np.array_equal(skirt_lines(tr), want)
    # given lines: the same bins, checked the same way
    assert np.array_equal(kbr_lines(tr, lines_hz=list(LINES)), want)
    assert np.array_equal(skirt_lines(tr, lines_hz=list(LINES)), want)


@pytest.mark.parametrize("lines_of", [kbr_lines, skirt_lines])
def test_lines_off_a_regular_grid_refused_by_both(lines_of):
    tr = lti_trial(lines=np.array([4, 36, 69, 99, 132]) / T)   # gaps 32, 33, 30, 33: gcd 1
    with pytest.raises(InputError, match="regular grid"):
        lines_of(tr)


@pytest.mark.parametrize("lines_of", [kbr_lines, skirt_lines])
def test_leakage_refused_by_both(lines_of):
    """The 25 lines, and a flat band of 80 bins above them (20 ... 22 Hz) holding 3 % of the power: no bin of
    the band stands above its neighbours, every line is found, but more than MAX_LEAKAGE of the power is
    off the lines (skirt had no such test before the merge)."""
    tr = lti_trial()
    X = np.fft.rfft(tr.input)
    rng = np.random.default_rng(0)
    band = np.arange(800, 880)
    power = 0.03 / 0.97 * np.sum(np.abs(X[1:]) ** 2)
    X[band] = np.sqrt(power / len(band)) * np.exp(2j * np.pi * rng.uniform(size=len(band)))
    leaky = Trial.from_arrays(np.fft.irfft(X, N), tr.output, FS, name="leaky")
    assert MAX_LEAKAGE < 0.03
    with pytest.raises(InputError, match=r"3 % of its power lies off the 25 detected line"):
        lines_of(leaky)
    assert np.array_equal(lines_of(leaky, lines_hz=list(LINES)), np.rint(LINES * T))   # given: no leakage test


@pytest.mark.parametrize("lines_of", [kbr_lines, skirt_lines])
def test_given_line_not_excited_refused_by_both(lines_of):
    with pytest.raises(InputError, match="1.3 Hz of lines_hz is not excited"):
        lines_of(lti_trial(), lines_hz=[0.1, 0.9, 1.3, 1.7])


@pytest.mark.parametrize("lines_of", [kbr_lines, skirt_lines])
def test_constant_input_refused_by_both(lines_of):
    with pytest.raises(InputError, match="constant .no power above DC"):
        lines_of(Trial.from_arrays(np.full(N, 0.3), np.zeros(N), FS))


def test_threshold_is_each_estimators_own():
    """A line 25 dB above the floor: a line at skirt's default threshold (20 dB), not at KBR's (30 dB)."""
    k = np.rint(LINES * T).astype(int)
    rng = np.random.default_rng(3)
    X = 10 ** (-25 / 20) * np.exp(2j * np.pi * rng.uniform(size=N // 2 + 1))   # every empty bin 25 dB down
    X[k] = 1.0
    X[0] = 0.0
    x = np.fft.irfft(X, N)
    assert np.array_equal(excited_bins("x", x, FS, 20.0, max_leakage=0.5), k)
    with pytest.raises(InputError, match="no clearly excited lines"):
        excited_bins("x", x, FS, 30.0, max_leakage=0.5)
    assert np.array_equal(multisine_bins("x", x, FS, 20.0, lines_hz=list(LINES)), k)
