"""The README's worked example: the `estimate` command on the five REKLAB ankle recordings.

Usage: python docs/ankle_example.py PATH/TO/ankle_stationary.npz OUTDIR
(`make example-ankle` passes ../shared/data/reklab-ankle/ankle_stationary.npz and docs/). Writes
OUTDIR/ankle_example.md (a table of I, B, K or stiffness with their 95 % confidence intervals, and the
VAF, per record and estimator) and two figures made by `--plot`. Developers' data only: nothing here is read by the package at runtime.
"""
from __future__ import annotations

import contextlib
import io
import re
import sys
import tempfile
from pathlib import Path

import pandas as pd

from jointbench.benchmarks.cli import main
from jointbench.benchmarks.tables import markdown

RECORDS = ["z_pf", "z_pf2", "z_df", "z_df2", "z_df3"]
COMMON = ["--decimate", "10", "--torque-sign", "-1"]          # REKLAB: 100 Hz, torque sign flipped
ESTIMATORS = {
    "ibk_irf": ["--set", "lag_before=40ms", "--set", "lag_after=40ms", "--set", "bandlimit=20Hz"],
    "irf2_ls": ["--set", "lag_before=40ms", "--set", "lag_after=40ms"],
    "spectral": [],
    "ibk_spectral": [],
}
FIGURES = {("z_df", "ibk_irf"): "ankle_z_df_ibk_irf.png", ("z_df", "spectral"): "ankle_z_df_spectral.png"}


def with_interval(frame: pd.DataFrame, col: str) -> str:
    """``value [lo, hi]`` from OUT.csv (the 95 % interval columns), or empty when the column is absent."""
    if col not in frame:
        return ""
    text = f"{frame[col].mean():.4g}"
    if f"{col}_lo" in frame:
        text += f" [{frame[f'{col}_lo'].mean():.4g}, {frame[f'{col}_hi'].mean():.4g}]"
    return text


def run(npz: Path, out: Path) -> pd.DataFrame:
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for rec in RECORDS:
            for name, extra in ESTIMATORS.items():
                csv = Path(tmp) / f"{rec}_{name}.csv"
                argv = ["estimate", "-e", name, "-i", f"{npz}:{rec}", "-o", str(csv), *COMMON, *extra]
                if (rec, name) in FIGURES:
                    argv += ["--plot", str(out / FIGURES[rec, name])]
                buf = io.StringIO()
                with contextlib.redirect_stdout(buf):
                    if main(argv) != 0:
                        raise SystemExit(f"estimate failed: {' '.join(argv)}")
                frame = pd.read_csv(csv)
                vaf = float(re.search(r"^\s+\S+\s+(-?[\d.]+) %", buf.getvalue(), re.M).group(1))
                row = {"record": rec, "estimator": name}
                for col in ("I", "B", "K", "stiffness"):
                    row[col] = with_interval(frame, col)
                row["VAF_%"] = vaf
                rows.append(row)
    return pd.DataFrame(rows)


if __name__ == "__main__":
    npz, out = Path(sys.argv[1]), Path(sys.argv[2])
    out.mkdir(parents=True, exist_ok=True)
    table = run(npz, out)
    (out / "ankle_example.md").write_text(markdown(table))
    print(table.to_string(index=False))
