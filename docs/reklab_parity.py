"""Parity with REKLAB's parallel cascade: the five stationary ankle trials, REKLAB's ``PC_stiffnessID`` (run in GNU
Octave: tools/reklab/) against JointBench's ``parallel_cascade`` with the same settings; and the simulated ankle
that chose where the velocity is taken (the ``differentiate`` setting's default).

Usage: python docs/reklab_parity.py PATH/TO/ankle_stationary.npz OUTDIR [--no-simulation]
(`make parity-reklab` passes ../shared/data/reklab-ankle/ankle_stationary.npz and docs/). Writes
OUTDIR/reklab_parity.md. Every number in it is computed here, from the reference CSV of tools/reklab/ (REKLAB's
numbers, with the toolbox commit) and from fits made here. ``--no-simulation`` leaves out the simulated section
(for a quick look; the committed page has it). Developers' data only: nothing here is read by the package.
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pandas as pd

from jointbench import api
from jointbench.benchmarks.harness.pages import markdown_table as markdown
from jointbench.core.scores import vaf
from jointbench.core.signal import velocity

REPO = Path(__file__).resolve().parents[1]
REFERENCE = REPO / "tools" / "reklab" / "pc_stiffnessID_rect.csv"
REFERENCE_IRFS = REPO / "tools" / "reklab" / "pc_stiffnessID_rect_irfs.csv"
RECORDS = ("z_pf", "z_pf2", "z_df", "z_df2", "z_df3")
DECIMATE = 10
#: REKLAB's torque is positive opposite to JointBench's convention for these trials (docs/ankle_example.md): the
#: fits are linear in the torque, so negating it negates K and the reflex gain exactly; REKLAB's are negated here
TORQUE_SIGN = -1
#: PC_stiffnessID's settings with the rectifier reflex of pcDemo.m, as parallel_cascade's: a +-40 ms two-sided
#: intrinsic IRF (nlag_intrinsic = ceil(0.04 / 0.01) = 4 lags each side), a one-sided reflex IRF of 1000 ms (100
#: lags from lag 0: no delay before it), the half-wave rectifier of the positive velocity, the toolbox's
#: pseudo-inverse IRFs, stop when the total VAF improves by less than 0.05 points, at most 10 iterations, the reflex
#: pathway always kept
SETTINGS = {"lag_before": 0.04, "lag_after": 0.04, "pseudo_inverse": "mdl", "delay": 0.0, "reflex_window": 0.99,
            "nonlinearity": "rectifier", "stretch": "positive", "tolerance": 0.05, "max_iter": 10,
            "keep_reflex": "always"}
#: the tolerances of issue 37 (intrinsic K 3 %, reflex gain 10 %); the VAF is reported, not judged
TOL_K, TOL_GAIN = 3.0, 10.0
#: the configurations compared: JointBench's anti-alias filter and where the velocity is taken
CONFIGS = {"matched": ("chebyshev", "before_decimation"),
           "FIR decimation": ("fir", "before_decimation"),
           "velocity after decimation": ("fir", "after_decimation")}


def reference() -> pd.DataFrame:
    """REKLAB's numbers (tools/reklab/pc_stiffnessID_rect.csv), K and the reflex gain negated (:data:`TORQUE_SIGN`)."""
    ref = pd.read_csv(REFERENCE).set_index("trial").loc[list(RECORDS)]
    return ref.assign(intrinsic_K=TORQUE_SIGN * ref["intrinsic_K"], reflex_gain=TORQUE_SIGN * ref["reflex_gain"])


def fit(npz: Path, record: str, decimate_filter: str, differentiate: str):
    """JointBench's parallel cascade on one trial with REKLAB's settings (the checked pipeline: decimation by 10)."""
    return api.fit("parallel_cascade", f"{npz}:{record}", settings={**SETTINGS, "differentiate": differentiate},
                   decimate=DECIMATE, decimate_filter=decimate_filter, torque_sign=TORQUE_SIGN)


def reflex_gain(est) -> float:
    """The reflex pathway's gain: the reflex IRF's sum times the rectifier's coefficient (N·m per rad/s)."""
    return float(np.sum(est.reflex_h) * est.nonlinearity.coef[0])


def irf_correlations(est, record: str) -> tuple[float, float]:
    """Correlation of JointBench's intrinsic and reflex IRFs with REKLAB's (same lags; REKLAB stores h / Ts)."""
    irfs = pd.read_csv(REFERENCE_IRFS)
    mine = irfs[irfs["trial"] == record]
    hi = TORQUE_SIGN * mine.loc[mine["pathway"] == "intrinsic", "h"].to_numpy() / est.fs
    hr = TORQUE_SIGN * mine.loc[mine["pathway"] == "reflex", "h"].to_numpy() / est.fs
    return float(np.corrcoef(hi, est.h)[0, 1]), float(np.corrcoef(hr, est.reflex_h)[0, 1])


def parity(npz: Path) -> pd.DataFrame:
    """One row per trial and configuration: REKLAB's and JointBench's intrinsic K, reflex gain, total VAF, their
    differences, and the IRFs' correlations."""
    ref = reference()
    rows = []
    for config, (filt, diff) in CONFIGS.items():
        for rec in RECORDS:
            est = fit(npz, rec, filt, diff).estimate
            K, g, r = float(est.stiffness(0.0)), reflex_gain(est), ref.loc[rec]
            ci, cr = irf_correlations(est, rec)
            rows.append({"config": config, "record": rec, "K_reklab": r["intrinsic_K"], "K_jointbench": K,
                         "K_diff_pct": 100 * (K / r["intrinsic_K"] - 1), "gain_reklab": r["reflex_gain"],
                         "gain_jointbench": g, "gain_diff_pct": 100 * (g / r["reflex_gain"] - 1),
                         "vaf_reklab": r["vaf_total"], "vaf_jointbench": est.vaf_total,
                         "vaf_diff": est.vaf_total - r["vaf_total"], "irf_corr_intrinsic": ci,
                         "irf_corr_reflex": cr, "iterations": est.fit_info["iterations"]})
    return pd.DataFrame(rows)


def within(df: pd.DataFrame) -> pd.Series:
    """Per row: both tolerances met."""
    return (df["K_diff_pct"].abs() <= TOL_K) & (df["gain_diff_pct"].abs() <= TOL_GAIN)


def parity_table(df: pd.DataFrame) -> pd.DataFrame:
    """The parity table of the matched configuration, as the page shows it."""
    m = df[df["config"] == "matched"]
    return pd.DataFrame({
        "record": m["record"],
        "intrinsic K REKLAB (N·m/rad)": m["K_reklab"].map("{:.2f}".format),
        "intrinsic K JointBench": m["K_jointbench"].map("{:.2f}".format),
        "K difference (%)": m["K_diff_pct"].map("{:+.1f}".format),
        "reflex gain REKLAB (N·m·s/rad)": m["gain_reklab"].map("{:.3f}".format),
        "reflex gain JointBench": m["gain_jointbench"].map("{:.3f}".format),
        "gain difference (%)": m["gain_diff_pct"].map("{:+.1f}".format),
        "total VAF REKLAB (%)": m["vaf_reklab"].map("{:.2f}".format),
        "total VAF JointBench (%)": m["vaf_jointbench"].map("{:.2f}".format),
        "within 3 % / 10 %": within(m).map({True: "yes", False: "no"})})


def configs_table(df: pd.DataFrame) -> pd.DataFrame:
    """The K and gain differences of every configuration, one row per trial."""
    out = {"record": list(RECORDS)}
    for config in CONFIGS:
        c = df[df["config"] == config].set_index("record").loc[list(RECORDS)]
        out[f"{config}: K (%)"] = c["K_diff_pct"].map("{:+.1f}".format).to_list()
        out[f"{config}: gain (%)"] = c["gain_diff_pct"].map("{:+.1f}".format).to_list()
    return pd.DataFrame(out)


# ------------------------------------------------------------------------------------- the simulated ankle
#: the simulated ankle: configs/models/ankle_reflex.yaml with a constant K (its reflex: gain 10 N·m·s/rad, delay
#: 40 ms, half-wave rectifier of the positive velocity, 3.2 Hz activation), the reflex study's stiff position servo
#: and torque noise, simulated at 5 kHz and recorded at 1 kHz (60 s), then decimated by 10 in the fit
TRUE_K, TRUE_GAIN, SEEDS = 140.0, 10.0, range(5)
PERTURBATIONS = {
    "the reflex study's multisine, to 19 Hz": {"kind": "multisine", "period": "10 s", "f_min": "0.1 Hz",
                                                "f_max": "19.3 Hz", "spacing": "0.8 Hz", "corner": "6 Hz",
                                                "slope": -20, "rms": "0.02 rad", "quiet": "5 s"},
    "noise through a 4th-order low-pass at 30 Hz": {"kind": "filtered_noise", "cutoff": "30 Hz", "order": 4,
                                            "rms": "0.015 rad"},
    "PRBS of 150 ms clock through the servo": {"kind": "prbs", "amplitude": 0.015, "clock": 0.15,
                                              "sequence": "random"},
}


def experiment(perturbation: dict) -> dict:
    return {"joint": dict(api.joint("ankle_reflex"), K=TRUE_K),
            "apparatus": {"kind": "position_servo", "stiffness": "30000 N.m/rad", "damping": "30 N.m.s/rad"},
            "perturbation": perturbation, "sensors": {"torque": {"noise_variance_ratio": 0.034}},
            "fs_sim": "5000 Hz", "duration": "60 s",
            "acquisition": {"detrend": False, "fs": "1000 Hz", "decimation": "fir", "trim": "0 s"}}


def velocity_band(trial) -> float:
    """The frequency (Hz) below which 90 % of the recorded velocity's power lies (central differences at 1 kHz)."""
    from scipy.signal import welch

    f, p = welch(velocity(trial, "after_decimation"), trial.fs, nperseg=4096)
    return float(f[np.searchsorted(np.cumsum(p) / p.sum(), 0.9)])


def simulated_fit(trial, differentiate: str) -> dict:
    """parallel_cascade (its defaults) on the trial decimated by 10, scored against the simulated truth."""
    f = api.fit("parallel_cascade", trial, settings={"differentiate": differentiate}, decimate=DECIMATE)
    est, t = f.estimate, f.trials[0]
    g = reflex_gain(est) if est.reflex_h is not None else 0.0
    rows = slice(*est.rows)
    true_r = t.truth.signals["reflex_torque"][rows]
    fit_r = est.reflex_torque(t.angle - t.angle.mean(), velocity(t, differentiate))[rows]
    return {"K_err_pct": 100 * (float(est.stiffness(0.0)) / TRUE_K - 1), "gain_err_pct": 100 * (g / TRUE_GAIN - 1),
            "separation": vaf(true_r - true_r.mean(), fit_r - fit_r.mean()), "vaf_total": est.vaf_total}


def simulation() -> pd.DataFrame:
    rows = []
    for name, pert in PERTURBATIONS.items():
        for seed in SEEDS:
            tr = api.simulate(experiment(pert), seed=seed)
            band = velocity_band(tr)
            for diff in ("before_decimation", "after_decimation"):
                rows.append({"perturbation": name, "seed": seed, "differentiate": diff, "velocity_band_hz": band,
                             **simulated_fit(tr, diff)})
    return pd.DataFrame(rows)


def simulation_table(sim: pd.DataFrame) -> pd.DataFrame:
    def cell(s: pd.Series, fmt: str) -> str:
        return f"{s.mean():{fmt}} [{s.min():{fmt}}, {s.max():{fmt}}]"

    rows = []
    for (pert, diff), g in sim.groupby(["perturbation", "differentiate"], sort=False):
        band = f"{pert} ({g['velocity_band_hz'].mean():.0f} Hz)"
        rows.append({"perturbation (90 % of the velocity's power below)": band,
                     "differentiate": diff, "intrinsic K error (%)": cell(g["K_err_pct"], "+.1f"),
                     "reflex gain error (%)": cell(g["gain_err_pct"], "+.1f"),
                     "reflex torque VAF (%)": cell(g["separation"], ".1f"),
                     "total VAF (%)": cell(g["vaf_total"], ".1f")})
    return pd.DataFrame(rows)


def simulation_sentences(sim: pd.DataFrame) -> list[str]:
    """Per perturbation, which setting is nearer the truth on each measure (derived from the numbers)."""
    out = []
    for pert, g in sim.groupby("perturbation", sort=False):
        m = g.groupby("differentiate").agg(K=("K_err_pct", lambda s: s.abs().mean()),
                                           gain=("gain_err_pct", lambda s: s.abs().mean()),
                                           sep=("separation", "mean"))
        b, a = m.loc["before_decimation"], m.loc["after_decimation"]
        nearer = [what for what, better in (("intrinsic K", b.K < a.K), ("reflex gain", b.gain < a.gain),
                                            ("reflex torque", b.sep > a.sep)) if better]
        out.append(f"- {pert}: before decimation is nearer the truth in "
                   + (", ".join(nearer) if nearer else "none of the three")
                   + f" (mean |K error| {b.K:.1f} % against {a.K:.1f} %, mean |gain error| {b.gain:.1f} % against "
                   f"{a.gain:.1f} %, reflex torque VAF {b.sep:.1f} % against {a.sep:.1f} %).")
    return out


# ------------------------------------------------------------------------------------------------- the page
def page(df: pd.DataFrame, sim: pd.DataFrame | None) -> str:
    ref = pd.read_csv(REFERENCE)
    m = df[df["config"] == "matched"]
    n_ok = int(within(m).sum())
    commit = ref["toolbox_commit"].iloc[0]
    lines = [
        "# Parity with REKLAB's parallel cascade",
        "",
        "Generated by `make parity-reklab` (`docs/reklab_parity.py`) from the five stationary ankle trials of the "
        "REKLAB toolbox (`../shared/data/reklab-ankle/`, the toolbox's `stiffnessID/experimental_data.mat` as "
        "arrays: 60 s at 1 kHz). Reference: REKLAB's `PC_stiffnessID` run in GNU Octave "
        f"{ref['octave'].iloc[0]} (signal package {ref['octave_signal'].iloc[0]}) by `tools/reklab/reference.py` and "
        f"`tools/reklab/pc_reference.m` on toolbox commit `{commit}` of `reklab/reklab_public`; its numbers are kept "
        "in `tools/reklab/pc_stiffnessID_rect.csv` (and the IRFs in `pc_stiffnessID_rect_irfs.csv`), not the "
        "toolbox (GPL-2). Octave reads the toolbox's classes (`nldat`, `irf`, `nlbl`) and runs `PC_stiffnessID` as "
        "published; it cannot read the `nldat` objects of `experimental_data.mat` (MCOS class data), so each trial "
        "is rebuilt as an `nldat` from the same arrays.",
        "",
        "Settings, as `pcDemo.m` calls it (`'reflex_id_method','rect'`) with `PC_stiffnessID`'s defaults, and as "
        "`parallel_cascade` takes them: decimation by 10 to 100 Hz (`decimate=10`); a two-sided intrinsic IRF of "
        "+-40 ms (`lag_before`, `lag_after` = 0.04); a one-sided reflex IRF of 1000 ms from lag 0 (`delay` = 0, "
        "`reflex_window` = 0.99 s: 100 lags) of the half-wave rectified velocity (`nonlinearity` = rectifier, "
        "`stretch` = positive); the toolbox's MDL pseudo-inverse (`pseudo_inverse` = mdl); stop when the total "
        "VAF improves by less than 0.05 point (`tolerance`), at most 10 iterations; the reflex pathway always kept "
        "(`keep_reflex` = always). REKLAB differentiates the angle at 1 kHz, then decimates (`differentiate` = "
        "before_decimation, the default), with MATLAB's and Octave's `decimate`, an 8th-order Chebyshev filter "
        "(`decimate_filter` = chebyshev; `jointbench estimate --decimate 10 --decimate-filter chebyshev`). The "
        "torque is negated (`torque_sign` = -1: JointBench's sign convention for these trials); every step of "
        "both fits is linear in the torque, so REKLAB's K and reflex gain are shown negated. Intrinsic K is the "
        "sum of the intrinsic IRF (times the sampling increment for REKLAB's, which stores h / Ts), the reflex "
        "gain the same of the reflex IRF (N·m per rad/s of rectified velocity); the total VAF is each tool's own "
        "(REKLAB's from sample 100, JointBench's on the samples both pathways reach).",
        "",
        "## The parity table",
        "",
        markdown(parity_table(df)),
        "",
        f"Within the tolerances (intrinsic K 3 %, reflex gain 10 %) on {n_ok} of the 5 trials. Total VAF: "
        f"JointBench {m['vaf_diff'].min():+.2f} to {m['vaf_diff'].max():+.2f} points. The IRFs' shapes: intrinsic "
        f"IRFs correlate {m['irf_corr_intrinsic'].min():.3f} to {m['irf_corr_intrinsic'].max():.3f}, reflex IRFs "
        f"{m['irf_corr_reflex'].min():.3f} to {m['irf_corr_reflex'].max():.3f}; JointBench iterated "
        f"{m['iterations'].min()} to {m['iterations'].max()} times.",
        "",
        "## What each difference contributes",
        "",
        "JointBench's K and reflex gain against REKLAB's (difference in %), with REKLAB's settings, in three "
        "configurations: matched (the table above); JointBench's own anti-alias filter (`decimate_filter` = fir, "
        "the default); and the velocity taken after decimation (`differentiate` = after_decimation, what "
        "`parallel_cascade` did before issue 37).",
        "",
        markdown(configs_table(df)),
        "",
        "Taking the velocity after decimation is the large difference: central differences at 100 Hz are 10 % "
        "low at 10 Hz and 23 % low at 19 Hz (`jointbench.core.differentiators.central`), so the rectified "
        "velocity is too small and the reflex gain comes out too large, the intrinsic IRF giving up what the "
        "reflex pathway takes. The anti-alias filter is the next: JointBench's FIR is -0.7 dB at 35 Hz and -6 dB "
        "at 40 Hz, the Chebyshev filter within 0.1 dB up to 40 Hz; the fitted model (a +-40 ms "
        "IRF and a rectifier) is not the whole joint, so the band the fit weighs moves its numbers. What remains "
        "in the matched configuration: REKLAB fits each IRF from correlations over the whole record (a Toeplitz "
        "auto-correlation, each signal linearly detrended per fit) and differentiates by a five-point parabola, "
        "JointBench by least squares on the samples every lag reaches and central differences.",
    ]
    if sim is not None:
        lines += [
            "",
            "## Where to differentiate: the default of `differentiate`",
            "",
            "The simulated ankle (`configs/models/ankle_reflex.yaml` with K = 140 N·m/rad constant; its reflex: "
            "gain 10 N·m·s/rad, delay 40 ms, half-wave rectifier of the positive velocity, 3.2 Hz activation; the "
            "reflex study's stiff position servo and torque noise), simulated at 5 kHz and recorded at 1 kHz "
            f"(60 s), seeds {SEEDS.start} to {SEEDS.stop - 1}, fitted by `parallel_cascade` with its defaults "
            "after decimation by 10 (`api.fit(..., decimate=10)`, the FIR filter), scored against the truth: "
            "intrinsic K against 140, the reflex gain against 10, the fitted reflex torque's VAF of the true one. "
            "Mean [min, max] over the seeds:",
            "",
            markdown(simulation_table(sim)),
            "",
            *simulation_sentences(sim),
            "",
            "The default is `before_decimation`, the nearer on the perturbations whose velocity lies within the "
            "band a 100 Hz fit keeps (the multisine, and the low-passed noise up to the anti-alias filter's edge): "
            "central differences at 100 Hz understate that velocity, so the reflex gain comes out too large. A PRBS "
            "through a stiff servo moves the joint in steps whose velocity reaches hundreds of Hz: the true reflex "
            "is driven by the rectified full-band velocity, which the rectified velocity of a 100 Hz record "
            "(taken before or after decimation) does not reproduce, and both settings miss the reflex gain, in "
            "opposite directions; fit such a record at a higher rate (decimate less).",
        ]
    lines += [
        "",
        "Reproduce: `make parity-reklab` (needs `../shared` beside the checkout); the reference numbers: "
        "`python -m tools.reklab.reference --toolbox PATH/TO/reklab_public` (GNU Octave with its signal "
        "package). From Python:",
        "",
        "```python",
        "from jointbench import api",
        "fit = api.fit('parallel_cascade', 'ankle_stationary.npz:z_pf2', decimate=10, decimate_filter='chebyshev',",
        "              torque_sign=-1, settings={'delay': 0, 'reflex_window': 0.99, 'tolerance': 0.05,",
        "                                        'max_iter': 10, 'keep_reflex': 'always'})",
        "```",
        "",
    ]
    return "\n".join(lines)


if __name__ == "__main__":
    npz, out = Path(sys.argv[1]), Path(sys.argv[2])
    out.mkdir(parents=True, exist_ok=True)
    frame = parity(npz)
    sim = None if "--no-simulation" in sys.argv[3:] else simulation()
    (out / "reklab_parity.md").write_text(page(frame, sim))
    print(frame.to_string(index=False))
    if sim is not None:
        print(simulation_table(sim).to_string(index=False))
