"""Issue 33, "intervals that cannot be right": fsewls's pointwise bands were +-3.5e7 at t = 0 (the EWLS's
information without its start, ``R0``) and of zero width 30 samples later (a symmetric approximation of the
noise's variance that is not a variance: negative on the diagonal near the start). Now the exact variance of
the EWLS's error under a tapered (positive semidefinite) autocovariance: finite, of positive width at every
sample, and of the steady span's size at the start."""
import numpy as np
import pytest

from jointbench import api
from jointbench.core.types import Trial
from tests.test_fsewls import FS, simulate


@pytest.fixture(scope="module")
def noisy_elbow():
    time, angle, torque, _, _ = simulate(12.0, seed=3)
    noise = np.random.default_rng(7).standard_normal(len(torque))
    return Trial.from_arrays(angle, torque + 0.05 * np.std(torque) * noise, FS, name="noisy")


@pytest.mark.parametrize("noise", [False, True])
def test_fsewls_bands_finite_and_wide_from_the_first_sample(noise, noisy_elbow):
    trial = noisy_elbow if noise else Trial.from_arrays(*simulate(12.0, seed=3)[1:3], FS, name="clean")
    est = api.fit("fsewls", trial).estimate
    steady = est.steady()
    for k in "IBK":
        lo, hi = (np.asarray(x, float) for x in est.intervals.bounds[k])
        width = hi - lo
        assert np.all(np.isfinite(width)) and np.all(width > 0), (k, int(np.sum(~(width > 0))))
        typical = np.median(width[steady])
        assert width[0] < 10 * typical and np.max(width) < 10 * typical, (k, width[0], typical)


def test_fsewls_band_holds_a_constant_stiffness_on_the_steady_span(noisy_elbow):
    est = api.fit("fsewls", noisy_elbow).estimate
    steady = est.steady()
    lo, hi = (np.asarray(x, float)[steady] for x in est.intervals.bounds["K"])
    assert np.mean((lo <= 40.0) & (40.0 <= hi)) > 0.8
