"""The parallel cascade on the real REKLAB ankle recordings (../shared/data/reklab-ankle; skipped where absent),
as docs/reflex_example.py runs it: decimated to 100 Hz, the torque sign flipped (the toolbox's convention)."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from jointbench import estimators

REKLAB = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "reklab-ankle" / "ankle_stationary.npz"
pytestmark = pytest.mark.skipif(not REKLAB.is_file(), reason="../shared/data/reklab-ankle not here (developers only)")


@pytest.fixture(scope="module")
def example():
    import importlib.util

    spec = importlib.util.spec_from_file_location("reflex_example", Path(__file__).resolve().parents[1] / "docs" /
                                                  "reflex_example.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


@pytest.mark.parametrize("record", ["z_pf", "z_df"])
def test_parallel_cascade_on_real_ankle_data(example, record):
    """On the real trials the cascade explains more of the torque than the intrinsic IRF alone (the toolbox's
    reading: a reflex pathway is there in a tonic contraction), the reflex pathway is kept by the MDL, its
    delay is inside the scanned range and the intrinsic stiffness is positive, with a finite interval."""
    tr = example.load(REKLAB, record)
    assert tr.fs == 100.0 and tr.n == 6000
    irf = estimators.make("irf2_ls", {"lag_before": 0.04, "lag_after": 0.04}).fit(tr)
    p_irf = irf.prediction(tr).vaf()
    pc = estimators.make("parallel_cascade").fit(tr)
    assert pc.reflex_h is not None and 2 <= pc.reflex_delay <= 10
    assert pc.vaf_total > p_irf + 1.0                      # percentage points
    assert 0 < pc.stiffness(0.0) and np.all(np.isfinite(pc.intervals.bounds["stiffness"]))
    assert abs(pc.prediction(tr).vaf() - pc.vaf_total) < 1e-9
