"""The Python API: everything ``jointbench`` does, from a script or a notebook (the CLI is a thin layer on it).

Fit recordings (or any arrays) through the same checked pipeline as ``jointbench estimate``::

    from jointbench import api
    fit = api.fit("ibk_irf", "ankle.npz:z_df", decimate=10, torque_sign=-1,
                  settings={"lag_before": "40 ms", "lag_after": "40 ms"})
    fit.estimate.parameters(), fit.vaf, fit.frame

Simulate a trial from a config mapping (joint models by name) or a study's scenario, and score against
the stiffness the estimator should find (:meth:`jointbench.core.types.Trial.frozen_stiffness`)::

    trial = api.simulate("matrix:xu1998_elbow", seed=0, duration="10 s")
    k_true = trial.frozen_stiffness()

Run a study (a shipped one, a study file or a mapping) and read its tidy rows and checks, and the run
history, as DataFrames::

    run = api.run("westwick2012", parts=["fig2"], out="results")
    run.rows, run.checks, api.History("results").runs()

This module is a room of its own above the harness (tests/test_architecture.py): it may use the core,
``jointbench.sims``, ``jointbench.estimators`` and ``jointbench.benchmarks``; only the command-line modules
sit on it. Everything heavy is imported inside the functions, and importing it changes nothing for the
caller (no BLAS thread limits, no environment variables). Errors are
:class:`~jointbench.core.errors.JointBenchError` subclasses whose messages name the arguments. Every public
function checks its arguments where they enter (:mod:`jointbench.core.arguments`: a wrong type or value is one
:class:`~jointbench.core.errors.ConfigError` line naming the argument); a rate may carry its unit (``fs="1 kHz"``),
settings are a mapping (``{"lag_before": "40 ms"}``, not the command line's ``"lag_before=40ms"``), and one text
may stand for a list of one name (``parts="fig2"``). See docs/api.md.
"""
from __future__ import annotations

import dataclasses
import os
from pathlib import Path
from typing import TYPE_CHECKING, Any, Mapping, Sequence

from jointbench.core import arguments as check
from jointbench.core.errors import ConfigError, argument
from jointbench.core.types import Trial

if TYPE_CHECKING:  # pragma: no cover
    import pandas as pd

    from jointbench.fitting.pipeline import Fit

__all__ = ["History", "StudyResult", "estimators", "experiment", "fetch_data", "fit", "joint", "load_plugin", "read",
           "run", "scenario", "scenarios", "score", "settings", "simulate"]


# ----------------------------------------------------------------------------------------- estimators
def estimators() -> "pd.DataFrame":
    """The registered estimators (built-in and from plugins): ``name, tags, summary, module``."""
    import pandas as pd

    from jointbench import estimators as reg

    rows = []
    for n in reg.REGISTRY.names():
        cls = reg.REGISTRY.get(n)
        rows.append({"name": n, "tags": ", ".join(sorted(reg.REGISTRY.tags(n))), "summary": reg.REGISTRY.summary(n),
                     "module": cls.__module__})
    return pd.DataFrame(rows)


def settings(estimator: str) -> "pd.DataFrame":
    """The settings of ``estimator``: ``key, type, default, meaning`` (units in the type column)."""
    import pandas as pd

    from jointbench import estimators as reg
    from jointbench.core.schema import describe

    check.text(estimator, "estimator")
    return pd.DataFrame(describe(reg.REGISTRY.get(estimator).Settings), columns=["key", "type", "default", "meaning"])


def load_plugin(ref: str):
    """Import an outside estimator module (a name, or the path of a ``.py`` file or package folder) and
    return its :class:`jointbench.core.plugins.Plugin` record; its estimators are then registered."""
    from jointbench.core import plugins

    return plugins.load(str(check.path(ref, "ref")), "load_plugin")


# ------------------------------------------------------------------------------------------------- data
def fetch_data(name: str, *, url: str | None = None, folder: str | Path | None = None) -> Path:
    """Download a recorded data set (``"reklab"``: REKLAB's five stationary ankle trials, GPL-2), check its pinned
    SHA-256 and store it in the user's data folder (``$JOINTBENCH_DATA``, else ``~/.cache/jointbench``); ``url``
    another address of the same file (a mirror, ``file://``). Returns the stored file
    (:func:`jointbench.fitting.fetch.fetch`)."""
    from jointbench.fitting import fetch

    return fetch.fetch(check.text(name, "name"), url=check.text(url, "url", optional=True),
                       folder=None if folder is None else check.path(folder, "folder"))


# ---------------------------------------------------------------------------------------------- fitting
def read(path: str | Path | Sequence[str | Path], *, array: str | None = None, fs: float | None = None,
         schedule: str | None = None):
    """Read records (CSV, NPZ, MATLAB ``.mat``; ``FILE:ARRAY`` picks an N x 2 array) as :func:`fit` and
    ``jointbench estimate --input`` read them: a list of :class:`~jointbench.core.types.Trial`, or the
    :class:`~jointbench.core.ensemble.Ensemble` of a file whose angle and torque are 2-D.

    ``schedule`` names a recorded scheduling variable (a CSV column, an NPZ/.mat array) to read beside the
    angle and torque into each trial's ``channels`` (``jointbench estimate --schedule``); the names derived
    from the angle (``angle_slow``, ``angle``) need none. Fitting several records as one ensemble is
    :func:`fit`'s choice (``ensemble=``)."""
    from jointbench.fitting import inputs

    return inputs.read_files(check.paths(path, "path"), array=check.text(array, "array", optional=True),
                             fs=check.rate(fs), schedule=check.text(schedule, "schedule", optional=True))


def fit(estimator, data=None, *, angle=None, torque=None, fs: float | None = None, array: str | None = None,
        settings: Mapping[str, Any] | None = None, decimate: int = 1, window=None, torque_sign: int = 1,
        ensemble: bool | None = None, schedule: str | None = None, decimate_filter: str = "fir") -> "Fit":
    """Fit ``estimator`` through the checked pipeline (:mod:`jointbench.fitting.pipeline`), the one that
    ``jointbench estimate`` runs: same steps, same numbers.

    Parameters
    ----------
    estimator : str or Estimator
        A registered name (``api.estimators()``) with ``settings``, or an estimator object.
    data : Trial, list of Trial, Ensemble, path or list of paths, optional
        The records (files are read as :func:`read` reads them). Or give the arrays ``angle`` and ``torque``
        (1-D: one record; 2-D, samples x realizations: an ensemble) with ``fs``.
    fs : float, optional
        The sampling rate (Hz) of ``angle`` and ``torque``, or of files that carry none.
    array : str, optional
        The N x 2 ``[angle, torque]`` array of NPZ/.mat files (or name it in the path: ``"ankle.npz:z_df"``).
    settings : mapping, optional
        The estimator's settings, checked strictly; units allowed (``{"lag_before": "40 ms"}``);
        ``auto=True`` chooses a time-varying method's smoothing from the data.
    decimate : int
        Decimate every record by this whole factor (anti-alias filtered) before the fit. The angle's velocity is
        taken before, at the recorded rate, for the estimators that differentiate it (their ``differentiate``
        setting).
    decimate_filter : {'fir', 'chebyshev'}
        The anti-alias filter (:func:`jointbench.core.signal.decimate`): JointBench's linear-phase FIR, or the
        Chebyshev IIR of MATLAB's and Octave's ``decimate``, the one the REKLAB toolbox's analyses use
        (docs/reklab_parity.md).
    window : (start, end) or str, optional
        Fit only this part of every record, seconds from its first sample (``(5, 45)``, ``"5s:45s"``);
        without it a gated multisine is cropped to its whole periods for the multisine methods.
    torque_sign : {1, -1}
        -1 negates every torque record.
    ensemble : bool, optional
        Fit several records as the realizations of one time-varying condition (default: when the estimator
        takes ensembles only; an Ensemble given is one unless ``ensemble=False``).
    schedule : str, optional
        The scheduling variable of a parameter-varying estimator (``pv_irf``): ``angle_slow`` or ``angle``
        (derived from the angle), or a recorded channel (read from files as :func:`read` does, or a trial's
        ``channels``); ``fit.estimate.stiffness_at(values)`` and ``stiffness_band(values)`` then give K at
        chosen values (``jointbench estimate --schedule NAME --at V1,V2``).

    Returns
    -------
    Fit
        ``estimate`` (:class:`~jointbench.core.estimate.Estimate`), ``frame`` (parameters over time with 95 %
        intervals), ``response`` (IRF/FRF), ``vaf`` (each record's predicted-torque VAF, %), ``predictions``,
        ``trials`` (as fitted), ``notes``, ``hints`` (:mod:`jointbench.fitting.hints`); ``plot(path)`` draws it.

    Raises
    ------
    ConfigError, InputError
        Bad settings or arguments, unusable data: one line naming the argument or the record.
    Refused
        (an InputError) The output gate (:func:`jointbench.fitting.pipeline.gate`) did not return the estimate:
        its prediction of a record it was fitted on is worse than a constant (``reason="negative_vaf"``), a
        parameter or bound is not finite (``"non_finite"``), an interval has zero width
        (``"degenerate_interval"``), or the estimator returned an invalid estimate (``"invalid_estimate"``).
        One line naming the cause and the settings to change; ``exc.diagnostics`` holds the numbers (the
        VAF of each record, the widths, ...). The VAF is always the torque's, predicted from the angle, also
        for a trial whose torque was imposed (a torque drive): the numbers its CSV gives.
    """
    from jointbench.core.signal import DECIMATION_FILTERS
    from jointbench.fitting import pipeline

    fs, settings = check.rate(fs), check.mapping(settings, "settings", "{'lag_before': '40 ms'}")
    decimate = check.whole(decimate, "decimate", minimum=1)
    decimate_filter = check.choice(decimate_filter, "decimate_filter", DECIMATION_FILTERS)
    array, schedule = check.text(array, "array", optional=True), check.text(schedule, "schedule", optional=True)
    ensemble = check.flag(ensemble, "ensemble", optional=True)
    return pipeline.fit(estimator, data, angle=angle, torque=torque, fs=fs, array=array, settings=settings,
                        decimate=decimate, window=window, torque_sign=torque_sign, ensemble=ensemble,
                        schedule=schedule, decimate_filter=decimate_filter)


def score(estimate, data, *, fs: float | None = None, array: str | None = None,
          torque_sign: int = 1) -> "pd.DataFrame":
    """How well ``estimate`` (an :class:`~jointbench.core.estimate.Estimate`, or a :class:`Fit`) predicts the
    torque of other records at its sampling rate (held-out trials, another condition), as :func:`fit` scores
    its own: one row per record, ``record, vaf, samples, definition`` (the VAF in %, on the samples the
    estimate predicts; ``definition`` says what is compared). ``data`` as in :func:`fit`."""
    import pandas as pd

    from jointbench.core.estimate import Estimate
    from jointbench.fitting import inputs, pipeline

    est = getattr(estimate, "estimate", estimate)
    if not isinstance(est, Estimate):
        raise ConfigError(f"{argument('estimate')}: expected an Estimate or a Fit (api.fit's result), got "
                          f"{type(estimate).__name__}")
    fs, array = check.rate(fs), check.text(array, "array", optional=True)
    records = pipeline.signed(list(inputs.records(data, fs=fs, array=array)), torque_sign)
    for t in records:
        if t.fs != est.fs:
            raise ConfigError(f"data: record '{t.name}' is sampled at {t.fs:g} Hz, the estimate at {est.fs:g} Hz; "
                              f"decimate the record first (api.fit's decimate= does it for a fit)")
    predictions = pipeline.score(est, records)
    return pd.DataFrame([{"record": t.name, "vaf": p.vaf(), "samples": int(p.used.sum()), "definition": p.definition}
                         for t, p in zip(records, predictions)])


# ------------------------------------------------------------------------------------------- simulating
def joint(name: str) -> dict:
    """The joint model ``name`` (a shipped model, ``configs/models/<name>.yaml``, or a YAML file's path) as
    its mapping, ready for an experiment's ``joint``."""
    from jointbench.benchmarks.config import load_yaml, resolve_joint

    name = str(check.path(name, "name")) if not isinstance(name, str) else check.text(name, "name")
    if name.endswith((".yaml", ".yml")):
        return load_yaml(Path(name))
    return resolve_joint(name, where="joint")


def scenarios() -> "pd.DataFrame":
    """The named experiments of the shipped studies: ``name`` (``study:scenario`` of a comparison grid,
    ``study:part`` of a part with an experiment), ``study``, ``kind``, ``description``.

    A study this installation cannot load (every part of ``apparatus`` runs on MuJoCo: without the
    ``[mujoco]`` extra) is left out, and said: one :class:`UserWarning` naming each study left out and why, and
    the frame's ``attrs["left_out"]`` (study -> the reason). A comparison grid whose MuJoCo rows cannot run
    here still lists its scenarios (they simulate on the analytic backend)."""
    import warnings

    import pandas as pd

    from jointbench.benchmarks.config import load_study
    from jointbench.benchmarks.locate import study_ids

    rows, left_out = [], {}
    for sid in study_ids():
        try:
            study = load_study(sid)
        except ConfigError as exc:   # e.g. a study on the mujoco backend without the [mujoco] extra
            left_out[sid] = str(exc).splitlines()[0]
            continue
        for pname, part in study.parts.items():
            if part.grid is not None:
                rows += [{"name": f"{sid}:{s}", "study": sid, "kind": "grid scenario", "description": part.description}
                         for s in part.grid.scenarios]
            elif part.experiment is not None:
                rows.append({"name": f"{sid}:{pname}", "study": sid, "kind": "part", "description": part.description})
    if left_out:
        warnings.warn("api.scenarios() leaves out what this installation cannot load: "
                      + "; ".join(f"study {sid}: {why}" for sid, why in left_out.items()), stacklevel=2)
    frame = pd.DataFrame(rows, columns=["name", "study", "kind", "description"])
    frame.attrs["left_out"] = left_out
    return frame


def scenario(name: str) -> dict:
    """The named experiment ``study:scenario`` (a comparison grid's scenario: ``{experiment, stiffness,
    discard, estimators}``) or ``study:part`` (``{experiment}``), joint models resolved, as a mapping to
    edit and pass to :func:`simulate`, :func:`experiment` or a study's ``scenarios``."""
    from jointbench.benchmarks.config import load_study

    sid, sep, key = check.text(name, "name").partition(":")
    if not sep or not key:
        raise ConfigError(f"scenario: expected 'study:scenario' or 'study:part' (see api.scenarios()), got {name!r}")
    study = load_study(sid)
    for part in study.parts.values():
        if part.grid is not None and key in part.grid.scenarios:
            sc = part.grid.scenarios[key]
            out = {"experiment": dict(sc.experiment), "estimators": dict(sc.estimators)}
            if sc.stiffness is not None:
                out["stiffness"] = dataclasses.asdict(sc.stiffness)
            if sc.discard is not None:
                out["discard"] = sc.discard
            return out
    if key in study.parts and study.parts[key].experiment is not None:
        return {"experiment": dict(study.parts[key].experiment)}
    raise ConfigError(f"scenario: {sid} has no scenario or part with an experiment named {key!r}; see api.scenarios()")


def experiment(config: Mapping[str, Any] | str | None = None, *, backend: str = "analytic", **changes):
    """A :class:`jointbench.sims.Experiment` from a config mapping (as a study's ``experiment``; ``joint``
    may name a model: ``joint="wrist_vanderuit2018"``) or a scenario name (:func:`scenario`); ``changes``
    replace top-level keys (``duration="10 s"``)."""
    from jointbench import sims
    from jointbench.benchmarks.config import check_backend, resolve_joint

    backend = check.text(backend, "backend")
    if isinstance(config, str):
        config = scenario(config)["experiment"]
    elif config is not None and not isinstance(config, Mapping):
        raise ConfigError(f"{argument('config')}: expected a mapping (an experiment's config) or a scenario name "
                          f"('study:scenario', see api.scenarios()), got {type(config).__name__}")
    mapping = {**dict(config or {}), **changes}
    if isinstance(mapping.get("joint"), str):
        mapping["joint"] = joint(mapping["joint"]) if mapping["joint"].endswith((".yaml", ".yml")) else \
            resolve_joint(mapping["joint"], where="experiment")
    return sims.Experiment.from_mapping(mapping, "experiment", backend=check_backend(backend, "backend"))


def simulate(config: Mapping[str, Any] | str | Any = None, seed: int = 0, *, backend: str | None = None,
             realization: int = 0, replicate: int = 0, name: str = "trial", **changes) -> Trial:
    """Simulate one trial of an experiment (a mapping, a scenario name or an :class:`~jointbench.sims.
    Experiment`; ``changes`` as in :func:`experiment`). The trial carries its truth: ``trial.truth`` and
    ``trial.frozen_stiffness()``, the stiffness an estimator should be scored against. Same config and
    seed, identical arrays."""
    import numpy as np

    from jointbench import sims

    seed = seed if isinstance(seed, np.random.SeedSequence) else check.whole(seed, "seed")
    realization, replicate = check.whole(realization, "realization"), check.whole(replicate, "replicate")
    name, backend = check.text(name, "name"), check.text(backend, "backend", optional=True)
    exp = config if isinstance(config, sims.Experiment) and not changes else \
        experiment(config, backend=backend or "analytic", **changes)
    return sims.simulate(exp, seed, backend, name=name, replicate=replicate, realization=realization)


# ------------------------------------------------------------------------------------------------ studies
@dataclasses.dataclass
class StudyResult:
    """A finished run: ``rows`` (tidy: one per metric of every case), ``checks`` (one per published check),
    ``cases`` (case id, status, from the cache or computed, error), ``failures`` (the failed cases),
    ``refusals`` (the cases whose estimate the output gate refused, status ``refused``, with the reason), and where
    it was written (``folder``, ``report``, history ``run_id``). ``expected_failures``: the study says failed
    cases are part of it."""

    study: str
    folder: Path
    rows: "pd.DataFrame"
    checks: "pd.DataFrame"
    cases: "pd.DataFrame"
    run_id: int | None
    wall_s: float
    expected_failures: bool = False

    @property
    def failures(self) -> "pd.DataFrame":
        return self.cases.loc[self.cases["status"] == "failed", ["case_id", "error"]].reset_index(drop=True)

    @property
    def refusals(self) -> "pd.DataFrame":
        """The cases with a refused estimate (the output gate, :func:`jointbench.fitting.pipeline.gate`), with the
        reason: status ``refused`` (every fit), or ``ok`` with the case's other fits kept."""
        return self.cases.loc[self.cases["refused"], ["case_id", "status", "error"]].reset_index(drop=True)

    @property
    def report(self) -> Path:
        return self.folder / "report.md"


def run(study: str | Path | Mapping[str, Any], *, parts: Sequence[str] | None = None, out: str | Path | None = None,
        executor: str | Any = "process", workers: int | None = None, scheduler: str | None = None,
        use_cache: bool = True, overrides: Sequence[str] = (), backend: str | None = None,
        plugins: Sequence[str] = (), budget: float | None = None, confirm: bool = False, progress: bool = False,
        record_as: str = "jointbench.api.run") -> StudyResult:
    """Run a study and return its rows and checks (``jointbench run`` is this call).

    ``study``: a shipped study's id, a study file's path (or its folder), or a study as a mapping (the YAML's
    content; its relative names are looked up in the current folder, then in the package), e.g. a comparison
    grid. ``out``: the results folder (default ``./results``). ``executor``: ``process`` (a pool of
    ``workers`` processes on this machine), ``serial`` (this process), ``dask`` (a local cluster, or the one
    at ``scheduler``) or a ``concurrent.futures`` executor. ``overrides``: ``PART.KEY=VALUE`` texts
    (``--set``). ``plugins``: outside estimator modules to import first. ``budget``: refuse a comparison grid
    estimated to take longer (minutes; default its config's), unless ``confirm``. ``record_as``: the command
    the run history records.
    """
    import pandas as pd

    from jointbench.benchmarks.config import check_backend
    from jointbench.benchmarks.harness.pool import make_executor
    from jointbench.benchmarks.study import run_study
    from jointbench.core import plugins as _plugins

    study = _study_reference(study)
    parts, overrides, plugins = check.texts(parts, "parts"), check.texts(overrides, "overrides"), \
        check.texts(plugins, "plugins")
    out = check.path(out, "out", optional=True)
    workers = check.optional_whole(workers, "workers", minimum=1)
    scheduler, record_as = check.text(scheduler, "scheduler", optional=True), check.text(record_as, "record_as")
    budget = None if budget is None else check.positive(budget, "budget", "min")
    use_cache, confirm, progress = (check.flag(v, k) for k, v in (("use_cache", use_cache), ("confirm", confirm),
                                                                    ("progress", progress)))
    if not isinstance(executor, str) and not callable(getattr(executor, "submit", None)):
        raise ConfigError(f"{argument('executor')}: expected 'process', 'serial', 'dask' or a concurrent.futures "
                          f"executor, got {type(executor).__name__}")
    for ref in plugins:
        _plugins.load(ref, argument("plugins"))
    if backend is not None:
        backend = check_backend(backend, argument("backend"))
    ref = dict(study) if isinstance(study, Mapping) else study
    serial = executor == "serial"
    own = isinstance(executor, str)
    exe = make_executor(executor, workers, scheduler) if own else executor     # checks the arguments, each kind
    if serial:
        exe = None                                # the runner's own serial path (one BLAS thread)
    try:
        r = run_study(ref, parts=list(parts) if parts else None, out_root=Path(out) if out else None,
                      serial=serial, workers=workers, use_cache=use_cache, progress=progress, command=record_as,
                      executor=exe, backend=backend, overrides=tuple(overrides), budget_minutes=budget,
                      confirm=confirm)
    finally:
        if own and exe is not None:
            exe.shutdown(wait=True)
    cases = pd.DataFrame([{"case_id": c.case.case_id, "status": c.status, "cached": bool(c.cached),
                           "error": c.error, "refused": bool(c.refusals)} for c in r.results],
                         columns=["case_id", "status", "cached", "error", "refused"])
    return StudyResult(r.study.id, r.folder, r.rows, r.checks, cases, r.run_id, r.wall_s, r.study.expected_failures)


def _study_reference(study):
    """``study`` of :func:`run` when it is a study id, a path or a mapping; one line naming it otherwise."""
    if isinstance(study, Mapping):
        return study
    if isinstance(study, str):
        return check.text(study, "study")
    if isinstance(study, os.PathLike):
        return Path(study)
    raise ConfigError(f"{argument('study')}: expected a study id, a study file's path or a study mapping, got "
                      f"{study!r}")


# ------------------------------------------------------------------------------------------------ history
class History:
    """The run history of a results folder, ``<out>/history.sqlite`` (default ``./results``): every run of
    every study, its cases, tidy rows and checks (``jointbench history``, ``jointbench diff``).

    Examples
    --------
    >>> h = api.History("results")                       # doctest: +SKIP
    >>> runs = h.runs(study="westwick2012"); h.checks(int(runs["id"].max()))   # doctest: +SKIP
    """

    def __init__(self, out: str | Path | None = None):
        from jointbench.benchmarks.study import HISTORY_FILE, results_root

        self.path = results_root(check.path(out, "out", optional=True)) / HISTORY_FILE

    def _open(self):
        from jointbench.benchmarks.harness.history import History as Store

        return Store(self.path, create=False)

    def runs(self, study: str | None = None, kind: str | None = None, limit: int | None = None) -> "pd.DataFrame":
        """One row per recorded run: its study, status, commit, code hash, counts of cases and checks, wall
        time and versions."""
        study, kind = check.text(study, "study", optional=True), check.text(kind, "kind", optional=True)
        limit = check.optional_whole(limit, "limit", minimum=1)
        with self._open() as h:
            return h.runs(study=study, kind=kind, limit=limit)

    def run(self, run_id: int) -> dict:
        """Recorded run ``run_id`` in full (parts, commit, environment, command, counts, error)."""
        run_id = check.whole(run_id, "run_id", minimum=1)
        with self._open() as h:
            return h.run(run_id)

    def rows(self, run_id: int) -> "pd.DataFrame":
        """The tidy rows of run ``run_id`` (case labels as columns)."""
        run_id = check.whole(run_id, "run_id", minimum=1)
        with self._open() as h:
            return h.rows(run_id)

    def checks(self, run_id: int) -> "pd.DataFrame":
        """The checks of run ``run_id`` (outcome, band, evidence)."""
        run_id = check.whole(run_id, "run_id", minimum=1)
        with self._open() as h:
            return h.checks(run_id)

    def cases(self, run_id: int) -> "pd.DataFrame":
        """The cases of run ``run_id`` (status, error, wall time, cached, cache key)."""
        run_id = check.whole(run_id, "run_id", minimum=1)
        with self._open() as h:
            return h.cases(run_id)

    def diff(self, before: int, after: int, config: str | Path | None = None):
        """What changed from run ``before`` to run ``after`` of one study (checks flipped, metrics drifted
        beyond the thresholds of ``config``, default the nightly's, failures, timings, versions): a
        :class:`~jointbench.benchmarks.harness.diff.RunDiff`."""
        from jointbench.benchmarks.harness.diff import diff_runs
        from jointbench.benchmarks.nightly import DEFAULT_CONFIG, load_config

        before, after = check.whole(before, "before", minimum=1), check.whole(after, "after", minimum=1)
        rules = load_config(check.path(config, "config", optional=True) or DEFAULT_CONFIG).rules
        with self._open() as h:
            return diff_runs(h, before, after, rules)
