"""What changed between two recorded runs of a study: checks, metrics, failures, timings, versions.

Used by ``jointbench diff RUN_A RUN_B`` and by the nightly report. A metric *drifted* when, for the same
case, estimator, metric and labels, ``|after - before| > abs + rel * |before|`` with the first threshold
rule whose pattern matches the metric name (``configs/nightly.yaml``); a value that appears or disappears
(NaN on one side) drifted too. Same code and libraries give bit-identical numbers, so any drift comes from
a change of code, config or library, and the thresholds say how much of it matters.
"""
from __future__ import annotations

import dataclasses
import fnmatch
import math

import numpy as np
import pandas as pd

from jointbench.benchmarks.config import EVIDENCE
from jointbench.benchmarks.harness.history import History
from jointbench.core.errors import ConfigError


@dataclasses.dataclass(frozen=True)
class Threshold:
    metric: str = "*"          # fnmatch pattern on the metric name
    abs: float = 0.0
    rel: float = 0.0

    def limit(self, before: np.ndarray) -> np.ndarray:
        return self.abs + self.rel * np.abs(before)


@dataclasses.dataclass(frozen=True)
class Rules:
    """What counts as a change (the ``thresholds`` and ``timing`` of ``configs/nightly.yaml``)."""

    thresholds: tuple[Threshold, ...] = (Threshold("*", 1e-12, 1e-9),)
    grow_factor: float = 1.5
    min_seconds: float = 5.0
    timing_is_regression: bool = False
    #: metrics that are wall-clock times (fnmatch patterns): they change on every run, so they never drift
    #: (a part's compute time is compared under ``timing``)
    wall_clock: tuple[str, ...] = ("fit_time_s",)

    def is_wall_clock(self, metric: str) -> bool:
        return any(fnmatch.fnmatchcase(metric, p) for p in self.wall_clock)

    def threshold(self, metric: str) -> Threshold:
        for t in self.thresholds:
            if fnmatch.fnmatchcase(metric, t.metric):
                return t
        return Threshold(metric, 0.0, 0.0)


@dataclasses.dataclass
class RunDiff:
    study: str
    before: dict
    after: dict
    checks: pd.DataFrame         # every check of either run: before/after status and reproduced
    flipped: pd.DataFrame        # checks whose status changed (change: regressed, improved, new, gone)
    drift: pd.DataFrame          # per part, estimator, metric: how many values drifted, by how much
    drift_rows: pd.DataFrame     # the drifted values themselves
    new_failures: pd.DataFrame   # cases that fail now and did not before
    fixed: pd.DataFrame          # cases that failed before and do not now
    coverage: pd.DataFrame       # per part: values only before / only after
    timings: pd.DataFrame        # per part: compute time before and after (cases computed in both)
    changes: list[tuple[str, str, str]]   # (what, before, after) of code, config and versions
    rules: Rules

    @property
    def timings_grew(self) -> pd.DataFrame:
        return self.timings[self.timings["grew"]] if len(self.timings) else self.timings

    @property
    def regressions(self) -> list[str]:
        """One line per reason to alert (empty: nothing regressed)."""
        out = []
        reg = self.flipped[self.flipped["change"] == "regressed"] if len(self.flipped) else self.flipped
        if len(reg):
            kinds = "; ".join(f"{kind} {len(g)}: {', '.join(g['check'])}" for kind, g in by_evidence(reg))
            out.append(f"{self.study}: {len(reg)} check(s) flipped from pass to miss ({kinds})")
        if len(self.drift):
            names = sorted({f"{r.part}/{r.estimator + ':' if r.estimator else ''}{r.metric}"
                            for r in self.drift.itertuples()})
            out.append(f"{self.study}: {len(names)} metric(s) drifted beyond their threshold: {', '.join(names)}")
        if len(self.new_failures):
            out.append(f"{self.study}: {len(self.new_failures)} case(s) fail that did not: "
                       f"{', '.join(self.new_failures['case_id'][:5])}"
                       + (" ..." if len(self.new_failures) > 5 else ""))
        gone = self.coverage[self.coverage["only_before"] > 0] if len(self.coverage) else self.coverage
        if len(gone):
            out.append(f"{self.study}: values missing that the previous run had, in part(s) "
                       f"{', '.join(gone['part'])}")
        if self.rules.timing_is_regression and len(self.timings_grew):
            out.append(f"{self.study}: compute time grew in part(s) {', '.join(self.timings_grew['part'])}")
        return out


#: kinds of evidence in the order the reports show them, then that of runs recorded before the kind was
EVIDENCE_ORDER = (*EVIDENCE, "unrecorded")


def by_evidence(checks: pd.DataFrame):
    """(kind, rows) per kind of evidence present in ``checks``, in :data:`EVIDENCE_ORDER`."""
    ev = checks["evidence"].fillna("unrecorded") if "evidence" in checks else pd.Series("unrecorded", checks.index)
    kinds = sorted(set(ev), key=lambda k: EVIDENCE_ORDER.index(k) if k in EVIDENCE_ORDER else len(EVIDENCE_ORDER))
    return [(k, checks[ev == k]) for k in kinds]


def _checks(history: History, a: int, b: int) -> tuple[pd.DataFrame, pd.DataFrame]:
    ca = history.checks(a).set_index("check_id")
    cb = history.checks(b).set_index("check_id")
    ids = list(cb.index) + [i for i in ca.index if i not in cb.index]
    recs = []
    for i in ids:
        x = ca.loc[i] if i in ca.index else None
        y = cb.loc[i] if i in cb.index else None
        src = y if y is not None else x
        before = None if x is None else x["status"]
        after = None if y is None else y["status"]
        if before == after:
            change = ""
        elif before is None:
            change = "new"
        elif after is None:
            change = "gone"
        else:
            change = "regressed" if before == "pass" else "improved" if after == "pass" else "changed"
        evidence = src["evidence"] if "evidence" in src.index and isinstance(src["evidence"], str) else "unrecorded"
        recs.append({"check": i, "evidence": evidence, "part": src["part"], "metric": src["metric"],
                     "description": src["description"],
                     "published": src["published"], "low": src["low"], "high": src["high"],
                     "before": before, "after": after, "change": change,
                     "reproduced_before": np.nan if x is None or x["reproduced"] is None else float(x["reproduced"]),
                     "reproduced_after": np.nan if y is None or y["reproduced"] is None else float(y["reproduced"])})
    df = pd.DataFrame(recs, columns=["check", "evidence", "part", "metric", "description", "published", "low", "high",
                                     "before", "after", "change", "reproduced_before", "reproduced_after"])
    return df, df[df["change"] != ""].reset_index(drop=True)


KEY = ["case_id", "estimator", "metric", "labels", "occurrence"]


def _values(history: History, run_id: int) -> pd.DataFrame:
    r = history.rows(run_id)
    r["occurrence"] = r.groupby(["case_id", "estimator", "metric", "labels"]).cumcount()
    return r


def _drift(history: History, a: int, b: int, rules: Rules):
    ra, rb = _values(history, a), _values(history, b)
    m = ra[KEY + ["part", "value"]].merge(rb[KEY + ["part", "value"]], on=KEY, how="outer",
                                          suffixes=("_before", "_after"), indicator=True)
    m["part"] = m["part_after"].fillna(m["part_before"])
    coverage = (m.assign(only_before=m["_merge"] == "left_only", only_after=m["_merge"] == "right_only")
                .groupby("part")[["only_before", "only_after"]].sum().astype(int).reset_index())
    coverage = coverage[(coverage["only_before"] > 0) | (coverage["only_after"] > 0)].reset_index(drop=True)
    both = m[m["_merge"] == "both"].copy()
    both = both[[not rules.is_wall_clock(str(mt)) for mt in both["metric"]]]
    x, y = both["value_before"].to_numpy(float), both["value_after"].to_numpy(float)
    limit = np.empty(len(both))
    for metric, idx in both.groupby("metric").indices.items():
        limit[idx] = rules.threshold(str(metric)).limit(x[idx])
    with np.errstate(invalid="ignore"):
        delta = y - x
        nan_x, nan_y = np.isnan(x), np.isnan(y)
        same_inf = np.isinf(x) & (x == y)
        drifted = np.where(nan_x | nan_y, nan_x != nan_y, ~same_inf & (np.abs(delta) > limit))
    both["delta"] = delta
    both["limit"] = limit
    rows = both[drifted].drop(columns=["_merge", "part_before", "part_after", "occurrence"])
    if len(rows):
        n_all = both.groupby(["part", "estimator", "metric"]).size()
        g = rows.groupby(["part", "estimator", "metric"], sort=True)
        drift = g.agg(n_drifted=("delta", "size"), max_abs_delta=("delta", lambda d: float(np.nanmax(np.abs(d)))
                                                                 if np.isfinite(d).any() else math.nan),
                      limit=("limit", "max"), example=("case_id", "first"),
                      before=("value_before", "first"), after=("value_after", "first")).reset_index()
        drift["n_compared"] = [int(n_all.loc[(p, e, mt)]) for p, e, mt in
                               zip(drift["part"], drift["estimator"], drift["metric"])]
    else:
        drift = pd.DataFrame(columns=["part", "estimator", "metric", "n_drifted", "max_abs_delta", "limit",
                                      "example", "before", "after", "n_compared"])
    return drift, rows.reset_index(drop=True), coverage


def _failures(history: History, a: int, b: int):
    ca = history.cases(a).set_index("case_id")
    cb = history.cases(b).set_index("case_id")
    common = ca.index.intersection(cb.index)
    new = [c for c in common if ca.loc[c, "status"] == "ok" and cb.loc[c, "status"] != "ok"]
    new += [c for c in cb.index.difference(ca.index) if cb.loc[c, "status"] != "ok"]
    fixed = [c for c in common if ca.loc[c, "status"] != "ok" and cb.loc[c, "status"] == "ok"]
    cols = ["case_id", "part", "error"]
    return (cb.loc[new].reset_index()[cols] if new else pd.DataFrame(columns=cols),
            ca.loc[fixed].reset_index()[cols] if fixed else pd.DataFrame(columns=cols))


def _timings(history: History, a: int, b: int, rules: Rules) -> pd.DataFrame:
    ca, cb = history.cases(a), history.cases(b)
    m = ca.merge(cb, on="case_id", suffixes=("_before", "_after"))
    m = m[(m["cached_before"] == 0) & (m["cached_after"] == 0) & (m["status_before"] == "ok")
          & (m["status_after"] == "ok")]
    if m.empty:
        return pd.DataFrame(columns=["part", "cases", "before_s", "after_s", "ratio", "grew"])
    t = m.groupby("part_after").agg(cases=("case_id", "size"), before_s=("wall_time_s_before", "sum"),
                                    after_s=("wall_time_s_after", "sum")).reset_index()
    t = t.rename(columns={"part_after": "part"})
    t["ratio"] = t["after_s"] / t["before_s"].where(t["before_s"] > 0)
    t["grew"] = (t["ratio"] > rules.grow_factor) & (t["after_s"] >= rules.min_seconds)
    return t


def _changes(a: dict, b: dict) -> list[tuple[str, str, str]]:
    out = []

    def add(what, x, y):
        if str(x) != str(y):
            out.append((what, str(x), str(y)))

    add("commit", a["commit_id"] + ("-dirty" if a["dirty"] else ""), b["commit_id"] + ("-dirty" if b["dirty"] else ""))
    add("code hash (modules that compute the cases)", a["code_hash"], b["code_hash"])
    add("study config", a["config_hash"], b["config_hash"])
    add("python", a["python"], b["python"])
    pa, pb = a["environment"].get("packages", {}), b["environment"].get("packages", {})
    for lib in sorted(set(pa) | set(pb)):
        add(lib, pa.get(lib, "-"), pb.get(lib, "-"))
    pa, pb = a["environment"].get("plugins") or {}, b["environment"].get("plugins") or {}
    for name in sorted(set(pa) | set(pb)):      # outside estimators: distribution, version, source hash
        add(f"plugin {name}", pa.get(name, "-"), pb.get(name, "-"))
    add("machine", a["machine"], b["machine"])
    return out


def diff_runs(history: History, before: int, after: int, rules: Rules | None = None) -> RunDiff:
    """Everything that changed from run ``before`` to run ``after`` (both recorded in ``history``)."""
    rules = rules or Rules()
    a, b = history.run(before), history.run(after)
    if a["study"] != b["study"]:
        raise ConfigError(f"runs {before} and {after} are of different studies ({a['study']}, {b['study']})")
    checks, flipped = _checks(history, before, after)
    drift, drift_rows, coverage = _drift(history, before, after, rules)
    new_failures, fixed = _failures(history, before, after)
    return RunDiff(study=b["study"], before=a, after=b, checks=checks, flipped=flipped, drift=drift,
                   drift_rows=drift_rows, new_failures=new_failures, fixed=fixed, coverage=coverage,
                   timings=_timings(history, before, after, rules), changes=_changes(a, b), rules=rules)
