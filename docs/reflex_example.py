"""Worked example: the parallel cascade on the five REKLAB ankle recordings (intrinsic and reflex stiffness).

Usage: python docs/reflex_example.py PATH/TO/ankle_stationary.npz OUTDIR
(`make example-reflex` passes ../shared/data/reklab-ankle/ankle_stationary.npz and docs/). Writes
OUTDIR/reflex_example.md (per record and reflex nonlinearity: the delay found, the total, intrinsic and reflex
VAF, the intrinsic stiffness with its 95 % interval beside the two-sided IRF's) and OUTDIR/reflex_example.png
(the intrinsic and reflex IRFs of one record and its torque split into the two pathways). Every number in
the markdown is computed here. Developers' data only: nothing here is read by the package at runtime.

As the REKLAB toolbox's analysis (../shared/data/reklab-ankle/README.md): decimated by 10 to 100 Hz (the angle's
velocity taken before, at 1 kHz, as the toolbox does: the reflex pathway's default), the torque's mean removed
(every estimator does), a +-40 ms intrinsic IRF; the torque sign flipped as in docs/ankle_example.py (the
toolbox's convention). Parity with the toolbox's own numbers: docs/reklab_parity.md.
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pandas as pd

from jointbench import estimators
from jointbench.benchmarks.harness.pages import markdown_table as markdown
from jointbench.core.signal import resample_trial, velocity
from jointbench.core.types import Trial

RECORDS = ["z_pf", "z_pf2", "z_df", "z_df2", "z_df3"]
DECIMATE, TORQUE_SIGN = 10, -1.0
#: the reflex pathway's static nonlinearity: the toolbox's rectifier of positive velocity, of negative velocity
#: (the dorsiflexors are stretched by plantarflexion), and a polynomial estimated with the IRF
PATHWAYS = {"rectifier +v": {"nonlinearity": "rectifier", "stretch": "positive"},
            "rectifier -v": {"nonlinearity": "rectifier", "stretch": "negative"},
            "polynomial": {"nonlinearity": "polynomial"}}
FIGURE_RECORD = "z_pf"


def load(npz: Path, record: str) -> Trial:
    d = np.load(npz)
    z, fs = d[record], float(d["fs"])
    return resample_trial(Trial.from_arrays(z[:, 0], TORQUE_SIGN * z[:, 1], fs, name=record), fs / DECIMATE)


def fmt(x: float, lohi=None) -> str:
    text = f"{x:.4g}"
    return text + (f" [{lohi[0]:.4g}, {lohi[1]:.4g}]" if lohi is not None else "")


def run(npz: Path) -> tuple[pd.DataFrame, dict]:
    rows, fits = [], {}
    irf_est = estimators.make("irf2_ls", {"lag_before": 0.04, "lag_after": 0.04})
    for rec in RECORDS:
        tr = load(npz, rec)
        irf = irf_est.fit(tr)
        k_irf = irf.intervals.bounds["stiffness"] if irf.intervals else None
        for label, settings in PATHWAYS.items():
            pc = estimators.make("parallel_cascade", settings).fit(tr)
            fits[rec, label] = (tr, pc)
            iv = pc.intervals.bounds["stiffness"] if pc.intervals else None
            rows.append({"record": rec, "reflex nonlinearity": label,
                         "reflex": "kept" if pc.reflex_h is not None else "not kept (MDL)",
                         "delay (ms)": f"{1e3 * pc.reflex_delay / tr.fs:g}" if pc.reflex_h is not None else "",
                         "VAF total (%)": f"{pc.vaf_total:.2f}", "VAF intrinsic (%)": f"{pc.vaf_intrinsic:.2f}",
                         "VAF reflex (%)": f"{pc.vaf_reflex:.2f}",
                         "intrinsic K (N·m/rad)": fmt(float(pc.stiffness(0.0)), iv),
                         "two-sided IRF K (N·m/rad)": fmt(float(irf.stiffness(0.0)), k_irf),
                         "iterations": pc.fit_info.get("iterations", "")})
    return pd.DataFrame(rows), fits


def figure(fits: dict, out: Path) -> str:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    best = max((k for k in fits if k[0] == FIGURE_RECORD), key=lambda k: fits[k][1].vaf_total)
    tr, pc = fits[best]
    u = tr.angle - tr.angle.mean()
    y = tr.torque - tr.torque.mean()
    fig, (a, b) = plt.subplots(2, 1, figsize=(7.5, 7))
    a.plot(pc.lags / tr.fs * 1e3, pc.h, "o-", label="intrinsic IRF (lags -40 ... 40 ms)")
    if pc.reflex_h is not None:
        lags = (pc.reflex_delay + np.arange(len(pc.reflex_h))) / tr.fs * 1e3
        a.plot(lags, pc.reflex_h * 10, "s-", ms=3, label="reflex IRF x 10 (N·m per rad/s of the rectified velocity)")
    a.axhline(0, color="0.7", lw=0.8)
    a.set_xlabel("lag (ms)")
    a.set_ylabel("IRF weight")
    a.set_title(f"{best[0]}, reflex nonlinearity '{best[1]}': the two pathways' IRFs")
    a.legend(fontsize=8)
    sl = slice(int(10 * tr.fs), int(14 * tr.fs))
    t = tr.time[sl]
    b.plot(t, y[sl], color="0.5", lw=1, label="measured torque (mean removed)")
    b.plot(t, pc.intrinsic_torque(u)[sl], lw=1, label=f"intrinsic pathway (VAF {pc.vaf_intrinsic:.1f} %)")
    b.plot(t, pc.reflex_torque(u, velocity(tr, pc.differentiate))[sl], lw=1,
           label=f"reflex pathway (VAF {pc.vaf_reflex:.1f} %)")
    b.set_xlabel("time (s)")
    b.set_ylabel("torque (N·m)")
    b.legend(fontsize=8)
    fig.tight_layout()
    name = "reflex_example.png"
    fig.savefig(out / name, dpi=110)
    plt.close(fig)
    return name


def _bound_sentence(kept: pd.DataFrame) -> str:
    """How many kept reflex pathways found the shortest delay allowed (derived from the table)."""
    lo = 1e3 * estimators.make("parallel_cascade").settings.delay_min
    at = kept[kept["delay (ms)"].astype(float) <= lo + 1e-9]
    if at.empty:
        return "No fit found the shortest delay allowed."
    return (f"In {len(at)} of the {len(kept)} kept fits the delay is the shortest allowed ({lo:g} ms: "
            + ", ".join(f"{r['record']} {r['reflex nonlinearity']}" for _, r in at.iterrows())
            + "): there the reflex pathway may be taking up dynamics the +-40 ms intrinsic IRF leaves out rather "
            "than a stretch reflex; a longer delay_min or longer intrinsic lags test that reading.")


def page(table: pd.DataFrame, figure_name: str) -> str:
    kept = table[table["reflex"] == "kept"]
    best = table.loc[table.groupby("record")["VAF total (%)"].apply(lambda s: s.astype(float).idxmax())]
    lines = [
        "# Worked example: intrinsic and reflex stiffness of the REKLAB ankle recordings",
        "",
        "Generated by `make example-reflex` (`docs/reflex_example.py`) from the five stationary ankle trials of the "
        "REKLAB toolbox (`../shared/data/reklab-ankle/`: tonic plantarflexor (`z_pf*`) and dorsiflexor (`z_df*`) "
        "contractions, a stiff position servo imposing a random perturbation, 60 s at 1 kHz). As the toolbox's own "
        "analysis: decimated by 10 to 100 Hz (the reflex pathway's velocity taken before, at 1 kHz), the parallel "
        "cascade of Kearney, Stein & Parameswaran (1997) with a +-40 ms intrinsic IRF and a reflex pathway of the "
        "delayed velocity (`parallel_cascade`: delay by MDL over 20-100 ms, reflex lag window 0.5 s, the pathway "
        "kept only when it lowers the MDL).",
        "",
        "The reflex pathway was tried with three static nonlinearities: the toolbox's half-wave rectifier of the "
        "positive velocity, the rectifier of the negative velocity, and a polynomial estimated with the IRF. "
        "VAFs are those of the measured torque by the whole model and by each pathway alone (the toolbox's VAFT, "
        "VAFi, VAFr); the intervals are the intrinsic IRF's segment-robust 95 % intervals (the reflex "
        "pathway's own uncertainty is not propagated into them).",
        "",
        markdown(table),
        "",
        f"The reflex pathway was kept in {len(kept)} of the {len(table)} fits. Per record, the nonlinearity with the "
        "highest total VAF: " + "; ".join(f"{r['record']}: {r['reflex nonlinearity']} "
                                           f"(reflex VAF {r['VAF reflex (%)']} %, "
                                            f"intrinsic K {r['intrinsic K (N·m/rad)'].split(' ')[0]} against the "
                                            f"two-sided IRF's {r['two-sided IRF K (N·m/rad)'].split(' ')[0]})"
                                            for _, r in best.iterrows()) + ".",
        "",
        _bound_sentence(kept),
        "",
        f"![The two pathways of {FIGURE_RECORD}]({figure_name})",
        "",
        "Reproduce: `make example-reflex` (needs `../shared` beside the checkout), or from Python:",
        "",
        "```python",
        "from jointbench import estimators",
        "pc = estimators.make('parallel_cascade').fit(trial)   # a Trial at 100 Hz",
        "pc.reflex_delay, pc.vaf_total, pc.vaf_intrinsic, pc.vaf_reflex, pc.stiffness(0.0)",
        "```",
        "",
    ]
    return "\n".join(lines)


if __name__ == "__main__":
    npz, out = Path(sys.argv[1]), Path(sys.argv[2])
    out.mkdir(parents=True, exist_ok=True)
    table, fits = run(npz)
    name = figure(fits, out)
    (out / "reflex_example.md").write_text(page(table, name))
    print(table.to_string(index=False))
