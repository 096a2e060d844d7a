"""Why a combination of a comparison grid does not run, and the rows and lines that say so.

:func:`jointbench.benchmarks.compare.grid.expand_grid` builds each combination's experiment here
(:func:`build_experiment`), skips the combinations that cannot run and goes on: the experiment cannot be
simulated, the estimator cannot identify from it or does not take the data, the grid's ``only`` rules, nothing to
tune, or the backend's extra is not installed (MuJoCo on the light install: the other backends' rows run).
"""
from __future__ import annotations

import json
import math
from typing import Mapping

from jointbench import sims
from jointbench.core.errors import ConfigError, Incompatible


def backend_missing(name: str) -> str | None:
    """Why simulation backend ``name`` cannot run in this installation (an extra not installed: MuJoCo without
    ``jointbench[mujoco]``), as the reason of the combinations on it, or None. Those combinations are skipped
    (the others run: the light install runs a grid's analytic rows) and :func:`missing_extra_lines` says so."""
    why = getattr(sims.BACKENDS.get(name), "unavailable", lambda: None)()
    return f"simulation backend {name!r} {why}" if why else None


def missing_extra_lines(skipped: list[dict]) -> list[str]:
    """One line per part and backend whose combinations were skipped because the backend's extra is not
    installed (:func:`backend_missing`): how many, and what to install."""
    counts: dict[tuple, int] = {}
    for s in skipped:
        if s.get("backend") is not None and s["reason"] == backend_missing(s["backend"]):
            key = (s.get("part", ""), s["backend"], s["reason"])
            counts[key] = counts.get(key, 0) + 1
    return [f"{part + ': ' if part else ''}{n} combination{'s' if n > 1 else ''} on backend {backend} left out "
            f"(the others run): {reason}" for (part, backend, reason), n in counts.items()]


def build_experiment(built: dict, mapping: Mapping, backend: str):
    """The experiment of ``mapping`` on ``backend``, built once (memo ``built``): an :class:`sims.Experiment`,
    the message of an :class:`Incompatible` (valid settings that cannot go together: the combination is
    skipped with it), or the :class:`ConfigError` of an invalid config (raised by the caller, with the others)."""
    key = json.dumps([mapping, backend], sort_keys=True, default=str)
    if key not in built:
        try:
            built[key] = sims.Experiment.from_mapping(mapping, "the experiment", backend=backend)
        except Incompatible as exc:
            built[key] = str(exc)
        except ConfigError as exc:
            built[key] = exc
    return built[key]


def skip_reason(only, combo: Mapping, cls, mode: str, exp, lacking: str | None, idle: str | None) -> str | None:
    """Why a combination does not run (None: it runs), the first that applies: its experiment cannot be
    simulated (``exp`` is the message), the estimator cannot identify from it (:meth:`supports`) or does not
    take the data, a rule of the grid's ``only``, nothing to tune (``idle``: its reason,
    :func:`jointbench.benchmarks.compare.tuning.nothing_to_tune`), and last the backend's extra
    missing (``lacking``: then ``exp`` was built on the analytic backend, to judge the estimator's reasons)."""
    if isinstance(exp, str) and not lacking:
        return exp
    return ((cls.supports(exp) if isinstance(exp, sims.Experiment) else None) or refusal(cls, mode)
            or next((rule.reason for rule in only if rule.skips({**combo, "data": mode})), None)
            or idle
            or lacking)


def refusal(cls, mode: str) -> str | None:
    """Why estimator class ``cls`` does not take ``mode`` data (single trials or ensembles), or None."""
    if mode in cls.accepts:
        return None
    takes = " or ".join({"trial": "single trials", "pooled": "pooled records", "ensemble": "ensembles"}[k]
                        for k in ("trial", "pooled", "ensemble") if k in cls.accepts)
    return f"{cls.name} takes {takes}, not {'an ensemble' if mode == 'ensemble' else 'a single trial'}"


def skipped_rows(study_id: str, skipped: list[dict]) -> list[dict]:
    """Tidy rows (metric ``skipped``, value NaN, the ``reason``) for the skipped combinations of a run."""
    rows = []
    for s in skipped:
        labels = {k: v for k, v in s.items() if k not in ("part", "estimator", "reason")}
        cid = s["part"] + "".join(f"-{k}={v}" for k, v in labels.items()) + f"-estimator={s['estimator']}"
        rows.append({"study": study_id, "part": s["part"], "case_id": cid, "estimator": s["estimator"],
                     "metric": "skipped", "value": math.nan, "status": "skipped", "reason": s["reason"], **labels})
    return rows
