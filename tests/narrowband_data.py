"""The narrow-band record of issue 33 and the conformance grid over it: a random-phase multisine angle to
12 Hz (lines every 0.1 Hz), 30 s at 500 Hz, exact derivatives, torque ``0.02 u'' + 0.6 u' + 120 u`` plus noise
of 10 % of the torque's variance through a 30 Hz low-pass (4th-order Butterworth).

``python -m tests.narrowband_data [ESTIMATOR ...] [--seeds N]`` prints the table of refused / held / missed /
VAF < 0 per (estimator, setting)."""
from __future__ import annotations

import dataclasses

import numpy as np

from jointbench.core.types import Trial
from jointbench.testing.data import NARROW_BAND_TRUTH as TRUTH, narrow_band

#: every estimator that fits a single LTI trial and returns intervals, at its lag settings (the default, 20, 40
#: and 100 ms) or its window-like ones (the default, half and double); the time-varying ones (fsewls, pv_irf)
#: judged by their band's mean over the samples they call valid
LAG_GRID = ({}, {"lag_before": "20ms", "lag_after": "20ms"}, {"lag_before": "40ms", "lag_after": "40ms"},
            {"lag_before": "100ms", "lag_after": "100ms"})
SEGMENTS = ({}, {"segment": "1s"}, {"segment": "4s"})
GRID = {
    "ibk_irf": LAG_GRID,
    "irf2_ls": LAG_GRID,
    "irf2_corr": LAG_GRID,
    "parallel_cascade": LAG_GRID,
    "pv_irf": LAG_GRID,
    "ibk_spectral": SEGMENTS,
    "spectral": SEGMENTS,
    "fsewls": ({}, {"forgetting": 10.0}, {"forgetting": 40.0}),
}


def narrowband_trial(seed: int, fs: float = 500.0, duration: float = 30.0, fmax: float = 12.0,
                     noise: float = 0.1) -> Trial:
    """Issue 33's narrow-band record, drawn from ``seed``: the conformance kit's own
    (:func:`jointbench.testing.data.narrow_band`), one home."""
    return narrow_band(seed, fs=fs, duration=duration, fmax=fmax, noise=noise).replace(name=f"nb{seed}")


@dataclasses.dataclass
class Tally:
    """Outcomes of one (estimator, setting) over seeds."""

    refused: int = 0
    held: int = 0
    missed: int = 0
    negative_vaf: int = 0
    notes: list = dataclasses.field(default_factory=list)


def tally(name: str, settings: dict, seeds) -> Tally:
    """Fit ``name`` with ``settings`` through :func:`jointbench.api.fit` on each seed's record; a fit holds
    when every interval it gives of I, B, K (or only the stiffness) contains the truth."""
    from jointbench import api
    from jointbench.core.ensemble import valid_mask
    from jointbench.core.errors import ConfigError, InputError, Refused

    out = Tally()
    for seed in seeds:
        try:
            fit = api.fit(name, narrowband_trial(seed), settings=dict(settings))
        except (InputError, ConfigError, Refused) as e:
            out.refused += 1
            out.notes.append(f"{seed}: refused: {str(e).splitlines()[0][:160]}")
            continue
        out.negative_vaf += bool(fit.vaf[0] < 0)
        iv = fit.estimate.intervals
        bounds = {} if iv is None else iv.bounds
        keys = [k for k in "IBK" if k in bounds] or (["stiffness"] if "stiffness" in bounds else [])
        ok = bool(keys)
        valid = valid_mask(fit.estimate)
        for k in keys:
            lo, hi = (float(np.mean(np.broadcast_to(x, valid.shape)[valid])) for x in bounds[k])
            truth = TRUTH["K" if k == "stiffness" else k]
            ok &= bool(lo <= truth <= hi and hi > lo)
        out.held += ok
        out.missed += not ok
        if not ok:
            out.notes.append(f"{seed}: missed vaf={fit.vaf[0]:.1f} " + " ".join(
                f"{k}=[{float(np.mean(bounds[k][0])):.4g}, {float(np.mean(bounds[k][1])):.4g}]" for k in keys))
    return out


def main(argv=None) -> None:
    import argparse

    p = argparse.ArgumentParser()
    p.add_argument("estimators", nargs="*")
    p.add_argument("--seeds", type=int, default=30)
    p.add_argument("--verbose", action="store_true")
    a = p.parse_args(argv)
    print(f"{'estimator':18s} {'setting':28s} refused held missed VAF<0")
    for name in a.estimators or GRID:
        for settings in GRID[name]:
            t = tally(name, settings, range(a.seeds))
            text = ",".join(f"{k}={v}" for k, v in settings.items()) or "default"
            print(f"{name:18s} {text:28s} {t.refused:7d} {t.held:4d} {t.missed:6d} {t.negative_vaf:5d}", flush=True)
            if a.verbose:
                for n in t.notes:
                    print("    ", n)


if __name__ == "__main__":
    main()
