"""Figure and tables of the reflex study (protocol ``reflex.bias``), drawn from the tidy rows.

Per part (one joint): the stiffness bias of every estimator against the reflex's share of the torque,
constant and time-varying gain, and the parallel cascades' separation of the pathways against the truth.
"""
from __future__ import annotations

import numpy as np
import pandas as pd

from jointbench.benchmarks.figures import PartReport, new_figure, register, save

#: the estimates that separate a reflex pathway (their separation metrics exist)
CASCADES = ("parallel_cascade", "tv_parallel_cascade")


def _ok(rows: pd.DataFrame) -> pd.DataFrame:
    return rows[rows["status"] == "ok"] if "status" in rows.columns else rows


def _mean(rows: pd.DataFrame, metric: str, by: list[str]) -> pd.DataFrame:
    """Mean of ``metric`` over realizations and seeds, per ``by``."""
    sel = rows[rows["metric"] == metric]
    by = [b for b in by if b in sel.columns]
    return sel.groupby(by, dropna=False)["value"].mean().reset_index()


def _share(rows: pd.DataFrame) -> pd.DataFrame:
    s = _mean(rows[rows["estimator"].fillna("") == ""], "reflex_share", ["gain", "variation"])
    return s.rename(columns={"value": "share"})


def bias_table(rows: pd.DataFrame) -> pd.DataFrame:
    """Rows: estimators (the reflex's share of the torque first); columns: gain and variation; values: the
    mean stiffness bias (%), or the reason an estimator was not fitted."""
    b = _mean(rows, "bias_mean_pct", ["estimator", "gain", "variation"])
    share = _share(rows)
    cols = sorted({(g, v) for g, v in zip(share["gain"], share["variation"])}, key=lambda x: (x[1], x[0]))
    out = {"": ["reflex share of the torque (%)"] + sorted(set(b["estimator"]) | _not_fitted(rows))}
    for g, v in cols:
        col = []
        sh = share[(share["gain"] == g) & (share["variation"] == v)]["share"]
        col.append(f"{float(sh.iloc[0]):.1f}" if len(sh) else "")
        for est in out[""][1:]:
            x = b[(b["estimator"] == est) & (b["gain"] == g) & (b["variation"] == v)]["value"]
            col.append(f"{float(x.iloc[0]):+.1f}" if len(x) and np.isfinite(x.iloc[0]) else "not fitted")
        out[f"G {g:g} ({v})"] = col
    return pd.DataFrame(out)


def _not_fitted(rows: pd.DataFrame) -> set:
    return set(rows[rows["metric"] == "not_fitted"]["estimator"])


def separation_table(rows: pd.DataFrame) -> pd.DataFrame:
    """The parallel cascades per gain and variation: their reflex VAF against the true one, the separation
    of each pathway (VAF against the true pathway torque), the delay error, how often the reflex was kept."""
    metrics = ["vaf_reflex", "vaf_reflex_true", "separation_intrinsic", "separation_reflex", "delay_error_samples",
               "reflex_kept", "bias_mean_pct"]
    sel = rows[rows["estimator"].isin(CASCADES) & rows["metric"].isin(metrics)]
    if sel.empty:
        return pd.DataFrame()
    t = sel.groupby(["estimator", "variation", "gain", "metric"])["value"].mean().unstack("metric").reset_index()
    names = {"vaf_reflex": "reflex VAF (%)", "vaf_reflex_true": "true reflex VAF (%)",
             "separation_intrinsic": "intrinsic torque VAF vs truth (%)",
             "separation_reflex": "reflex torque VAF vs truth (%)",
             "delay_error_samples": "delay error (samples)", "reflex_kept": "reflex kept (fraction)",
             "bias_mean_pct": "K bias (%)"}
    t = t.rename(columns=names)
    for c in t.columns:
        if t[c].dtype.kind == "f":
            t[c] = t[c].map(lambda x: "" if not np.isfinite(x) else f"{x:.3g}")
    return t


def _realizations(rows: pd.DataFrame) -> int:
    r = rows["realization"].dropna() if "realization" in rows.columns else pd.Series(dtype=float)
    return int(r.nunique()) if len(r) else 1


def _summary(rows: pd.DataFrame) -> str:
    """Sentences derived from the rows: the strongest constant reflex, each estimator's bias then (values, in
    name order: no estimator is called better, which would need a paired test)."""
    share = _share(rows)
    const = share[share["variation"] == "constant"]
    if const.empty:
        return ""
    gmax = float(const["gain"].max())
    sh = float(const[const["gain"] == gmax]["share"].iloc[0])
    b = _mean(rows, "bias_mean_pct", ["estimator", "gain", "variation"])
    b0 = b[(b["gain"] == 0) & (b["variation"] == "constant")].set_index("estimator")["value"]
    bm = b[(b["gain"] == gmax) & (b["variation"] == "constant")].set_index("estimator")["value"]
    delta = (bm - b0.reindex(bm.index)).dropna().sort_index()
    if delta.empty:
        return ""
    parts = ", ".join(f"{e} {v:+.1f}" for e, v in delta.items())
    return (f"At the strongest constant reflex (gain {gmax:g} N·m·s/rad, {sh:.0f} % of the torque variance) the "
            f"reflex adds to each estimator's stiffness bias (percentage points against its bias without a reflex; "
            f"one seed of {_realizations(rows)} realizations, no test between estimators, in name order): {parts}.")


@register("reflex.bias")
def reflex_bias(part, rows, curves, folder, checks) -> PartReport:
    rows = _ok(rows)
    b = _mean(rows, "bias_mean_pct", ["estimator", "gain", "variation"])
    share = _share(rows)
    b = b.merge(share, on=["gain", "variation"], how="left")
    fig, axes = new_figure(2, 2, figsize=(11, 8.5))
    (a, c), (d, e) = axes
    ests = sorted(set(b["estimator"]))
    colours = dict(zip(ests, [f"C{i}" for i in range(len(ests))]))
    for ax, var in ((a, "constant"), (c, "sine")):
        for est in ests:
            s = b[(b["estimator"] == est) & (b["variation"] == var)].sort_values("share")
            style = "-o" if est in CASCADES else "--."
            ax.plot(s["share"], s["value"], style, color=colours[est], lw=1.2 if est in CASCADES else 0.9, ms=4,
                    label=est)
        ax.axhline(0, color="0.7", lw=0.8)
        ax.set_xlabel("reflex share of the torque variance (%)")
        ax.set_ylabel("stiffness bias (% of the intrinsic K)")
        ax.set_title(f"{part.name}: {'constant' if var == 'constant' else 'time-varying (sine)'} reflex gain")
        ax.set_yscale("symlog", linthresh=10)
    a.legend(fontsize=7, ncol=2)
    sep = rows[rows["estimator"].isin(CASCADES)]
    for est, mk in zip(CASCADES, ("o", "s")):
        for metric, col in (("separation_reflex", "tab:red"), ("separation_intrinsic", "tab:blue")):
            for var, ls in (("constant", "-"), ("sine", "--")):
                s = _mean(sep[(sep["estimator"] == est) & (sep["variation"] == var)], metric, ["gain"])
                s = s[s["gain"] > 0] if metric == "separation_reflex" else s
                d.plot(s["gain"], s["value"], ls + mk, color=col, ms=4, lw=1,
                       label=f"{est}: {metric.split('_')[1]} torque, {var}")
        t = _mean(sep[sep["estimator"] == est], "vaf_reflex", ["gain", "variation"])
        tt = _mean(sep[sep["estimator"] == est], "vaf_reflex_true", ["gain", "variation"])
        m = t.merge(tt, on=["gain", "variation"], suffixes=("_est", "_true"))
        e.plot(m["value_true"], m["value_est"], mk, ms=5, label=est)
    lim = [min(0.0, e.get_xlim()[0]), max(60.0, e.get_xlim()[1])]
    e.plot(lim, lim, "k:", lw=0.8, label="equal")
    e.set_xlabel("true reflex VAF of the torque (%)")
    e.set_ylabel("estimated reflex VAF (%)")
    e.set_title("Reflex VAF: estimate against the truth")
    e.legend(fontsize=7)
    d.set_xlabel("reflex gain (N·m·s/rad)")
    d.set_ylabel("VAF against the true pathway torque (%)")
    d.set_ylim(0, 101)
    d.set_title("Separation of the pathways")
    d.legend(fontsize=6)
    fig.tight_layout()
    name = save(fig, folder, f"reflex_{part.name}.png")
    tables = [(f"{part.name}: stiffness bias (% of the intrinsic K, mean over the scored samples and realizations) "
               f"by reflex gain (N·m·s/rad)", bias_table(rows))]
    st = separation_table(rows)
    if not st.empty:
        tables.append((f"{part.name}: the parallel cascades' separation (means over realizations)", st))
    nf = rows[rows["metric"] == "not_fitted"]
    text = _summary(rows)
    if len(nf):
        reasons = nf.groupby("estimator")["reason"].first() if "reason" in nf.columns else pd.Series(dtype=str)
        text += " Not fitted: " + "; ".join(f"{k}: {v}" for k, v in reasons.items()) + "."
    return PartReport(figures=[(name, f"{part.name}: stiffness bias against the reflex's share of the torque, "
                                      f"constant (top left) and time-varying gain (top right); the parallel cascades' "
                                      f"separation (bottom left) and reflex VAF (bottom right).")],
                      tables=tables, text=text)
