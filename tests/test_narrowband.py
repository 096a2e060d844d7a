"""Issue 33, "intervals that cannot be right": on the narrow-band record (a multisine angle to 12 Hz, torque noise
low-passed at 30 Hz: :mod:`tests.narrowband_data`) every single-trial LTI estimator that gives intervals either
refuses in one line or returns intervals of positive width that hold the truth, and never a prediction worse
than a constant. The fast test takes a few seeds at one setting per estimator; the whole grid over 30 seeds,
against the acceptance's 85 %, is the conformance kit's check_narrow_band (``make conformance``)."""
import numpy as np
import pytest

from jointbench import estimators
from tests.narrowband_data import GRID, TRUTH, narrowband_trial, tally

#: one setting per estimator for the fast test (the papers' ensemble lags, or the default window)
FAST = {"ibk_irf": {"lag_before": "40ms", "lag_after": "40ms"}, "irf2_ls": {}, "irf2_corr": {},
        "ibk_spectral": {}, "spectral": {}}


@pytest.mark.parametrize("name", sorted(FAST))
def test_narrowband_intervals_hold_or_refuse(name):
    t = tally(name, FAST[name], range(3))
    assert t.negative_vaf == 0, t.notes
    assert t.refused == 3 or t.held == 3, t.notes


def test_narrowband_grid_covers_every_interval_estimator():
    """The grid names every registered single-trial LTI estimator that returns intervals (a new one must be added)."""
    lti = set(estimators.REGISTRY.names("lti"))
    assert lti <= set(GRID), lti - set(GRID)


@pytest.mark.parametrize("lags", ["20ms", "100ms"])
def test_ibk_irf_intervals_have_width_where_a_direction_is_barely_excited(lags):
    """The MDL keeps, for the coloured noise's chance share, a lag direction excited 10^-8 of the strongest; its
    variance must not swamp the others' (it did: I = 0.00042 [0.00042, 0.00042], VAF -19 584 %, seed 3)."""
    for seed in (3, 5):
        est = estimators.make("ibk_irf", {"lag_before": lags, "lag_after": lags}).fit(narrowband_trial(seed))
        for k in "IBK":
            lo, hi = est.intervals.bounds[k]
            assert np.isfinite(lo) and np.isfinite(hi) and hi - lo > 1e-3 * abs(TRUTH[k])
            assert hi - lo < abs(TRUTH[k]), (k, lo, hi)


def test_irf2_ls_stiffness_interval_has_width():
    """The stiffness ``sum(h)`` of the same IRF (it was 120.5 [120.5, 120.5] at seed 3, 118.8 [118.8, 118.8] at 4)."""
    for seed in (3, 4):
        lo, hi = estimators.make("irf2_ls", {}).fit(narrowband_trial(seed)).intervals.bounds["stiffness"]
        assert 0.1 < hi - lo < 60.0 and lo <= TRUTH["K"] <= hi, (seed, lo, hi)


# The 30-seed grid of issue 33's acceptance is the conformance kit's check_narrow_band (make conformance:
# tests/test_conformance.py::test_full_conformance), judged pointwise; one home for it.
