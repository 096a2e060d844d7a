"""The one VAF (jointbench.core.scores.vaf): hand values and its stated behaviour on degenerate input."""
import numpy as np
import pytest

from jointbench.core.errors import InputError
from jointbench.core.scores import vaf

Y = np.array([1.0, -1.0, 1.0, -1.0])              # var 1


def test_hand_values_and_an_offset():
    assert vaf(Y, Y) == pytest.approx(100.0)
    assert vaf(Y, np.zeros(4)) == pytest.approx(0.0)
    assert vaf(Y, 0.5 * Y) == pytest.approx(75.0)
    assert vaf(Y, Y + 3.0) == pytest.approx(100.0)                    # an offset is not variance
    assert vaf(Y, Y + 0.5, bias_counts=True) == pytest.approx(75.0)   # ... unless it counts
    assert vaf(Y, -Y) == pytest.approx(-300.0)                        # worse than the mean: negative


def test_pooled_records_and_one_mean_per_record():
    y = np.column_stack([Y, Y + 10.0])                                # two records, means 0 and 10
    yhat = np.column_stack([Y, Y])
    assert vaf(y, yhat, bias_counts=True, axis=0) == pytest.approx(100 * (1 - 100 / 2 / 1))
    assert vaf(y, y, axis=0) == pytest.approx(100.0)
    # pooled about the grand mean, the records' offset is variance to explain
    assert vaf(y, yhat, bias_counts=True) == pytest.approx(100 * (1 - 50 / 26))


def test_equals_the_textbook_formula_on_random_signals():
    rng = np.random.default_rng(3)
    for _ in range(5):
        y, yhat = rng.normal(size=200), rng.normal(size=200)
        assert vaf(y, yhat) == 100.0 * (1.0 - np.var(y - yhat) / np.var(y))


@pytest.mark.parametrize("y, yhat, cause", [
    (np.ones(5), np.zeros(5), "does not vary"),                      # constant truth
    (np.full(5, np.nan), np.zeros(5), "not finite"),                   # all-NaN
    (Y, np.r_[0.0, np.nan, 0.0, 0.0], "not finite"),                   # a NaN in the prediction
    (Y, np.r_[0.0, np.inf, 0.0, 0.0], "not finite"),
    (np.array([1.0]), np.array([1.0]), "1 sample"),                    # too short
    (np.array([]), np.array([]), "0 sample"),
])
def test_undefined_raises_or_is_nan_when_asked(y, yhat, cause):
    with pytest.raises(InputError, match=cause):
        vaf(y, yhat)
    assert np.isnan(vaf(y, yhat, undefined="nan"))


def test_mismatched_lengths_always_raise():
    for undefined in ("raise", "nan"):
        with pytest.raises(InputError, match="shape"):
            vaf(np.ones(3), np.ones(4), undefined=undefined)
    with pytest.raises(ValueError, match="undefined"):
        vaf(Y, Y, undefined="zero")
