"""The figure of the generic protocol ``parametric_fit`` (:mod:`benchmarks.protocols.generic`): each estimator's
spectral estimate beside its second-order fit and the truth, and the fitted parameters over seeds."""
from __future__ import annotations

from jointbench.benchmarks.figures import PartReport, first_seed, new_figure, register, save, summary_over_seeds


@register("parametric_fit")
def parametric_fit(part, rows, curves, folder, checks) -> PartReport:
    figs = []
    c0 = first_seed(curves)
    for est, c in c0.groupby("estimator"):
        if not (c["curve"] == "frf_mag").any():
            continue
        fig, (a, b, g) = new_figure(3, 1, figsize=(6.5, 7), sharex=True)
        for series, s in c[c["curve"] == "frf_mag"].groupby("series"):
            a.loglog(s["x"], s["y"], {"estimate": "k-", "model": "r--", "truth": "b:"}[series], label=series)
        for series, s in c[c["curve"] == "frf_phase"].groupby("series"):
            b.semilogx(s["x"], s["y"], {"estimate": "k-", "model": "r--", "truth": "b:"}[series])
        s = c[c["curve"] == "coherence2"]
        g.semilogx(s["x"], s["y"], "k-")
        a.set_ylabel("|impedance| (N·m/rad)")
        b.set_ylabel("phase (deg)")
        g.set_ylabel("coherence²")
        g.set_xlabel("frequency (Hz)")
        a.legend(fontsize=8)
        a.set_title(f"{est}: spectral estimate and second-order fit (seed {int(c0['seed'].min())})")
        figs.append((save(fig, folder, f"{part.name}_{est}.png"), f"{part.description} ({est})"))
    return PartReport(figures=figs, tables=[("Fitted parameters (median and range over seeds)",
                                             summary_over_seeds(rows, part.name, []))])
