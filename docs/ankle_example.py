"""The README's worked example: four estimators on the five REKLAB ankle recordings, with the Python API.

Usage: python docs/ankle_example.py PATH/TO/ankle_stationary.npz OUTDIR
(`make example-ankle` passes ../shared/data/reklab-ankle/ankle_stationary.npz and docs/). Writes
OUTDIR/ankle_example.md (a table of I, B, K or stiffness with their 95 % confidence intervals, and the
VAF, per record and estimator) and two figures. Each fit is :func:`jointbench.api.fit`, the checked pipeline
of `jointbench estimate` (the same numbers as the command). Developers' data only: nothing here is read by
the package at runtime.
"""
from __future__ import annotations

import sys
from pathlib import Path

import pandas as pd

from jointbench import api
from jointbench.benchmarks.harness.pages import markdown_table as markdown

RECORDS = ["z_pf", "z_pf2", "z_df", "z_df2", "z_df3"]
COMMON = {"decimate": 10, "torque_sign": -1}                  # REKLAB: 100 Hz, torque sign flipped
ESTIMATORS = {
    "ibk_irf": {"lag_before": "40 ms", "lag_after": "40 ms", "bandlimit": "20 Hz"},
    "irf2_ls": {"lag_before": "40 ms", "lag_after": "40 ms"},
    "spectral": {},
    "ibk_spectral": {},
}
FIGURES = {("z_df", "ibk_irf"): "ankle_z_df_ibk_irf.png", ("z_df", "spectral"): "ankle_z_df_spectral.png"}


def with_interval(frame: pd.DataFrame, col: str) -> str:
    """``value [lo, hi]`` from the estimate's frame (its 95 % interval columns), or empty when absent."""
    if col not in frame:
        return ""
    text = f"{frame[col].mean():.4g}"
    if f"{col}_lo" in frame:
        text += f" [{frame[f'{col}_lo'].mean():.4g}, {frame[f'{col}_hi'].mean():.4g}]"
    return text


def run(npz: Path, out: Path) -> pd.DataFrame:
    rows = []
    for rec in RECORDS:
        for name, settings in ESTIMATORS.items():
            fit = api.fit(name, f"{npz}:{rec}", settings=settings, **COMMON)
            if (rec, name) in FIGURES:
                fit.plot(out / FIGURES[rec, name])
            row = {"record": rec, "estimator": name}
            for col in ("I", "B", "K", "stiffness"):
                row[col] = with_interval(fit.frame, col)
            row["VAF_%"] = round(fit.vaf[0], 1)
            rows.append(row)
    return pd.DataFrame(rows)


if __name__ == "__main__":
    npz, out = Path(sys.argv[1]), Path(sys.argv[2])
    out.mkdir(parents=True, exist_ok=True)
    table = run(npz, out)
    (out / "ankle_example.md").write_text(markdown(table))
    print(table.to_string(index=False))
