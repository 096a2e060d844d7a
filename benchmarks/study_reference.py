"""The reference of a study's files, generated from the schema: ``docs/study_yaml.md``.

Every key of ``study.yaml`` and ``published.yaml`` that the parser accepts (:func:`jointbench.core.schema.parse`
on the specs of :mod:`benchmarks.config`, :mod:`benchmarks.published`, :mod:`benchmarks.compare.grid`,
:class:`sims.Experiment`, the registries' joint models, apparatus, perturbations, profiles and reflex pathways,
the protocols' parameters and the estimators' settings): its type, unit, default, allowed values and meaning,
read from the dataclass fields and their :func:`~jointbench.core.schema.param` metadata (the meaning falls back
on the class's numpydoc ``Parameters``), with the rules that are not one key's (how values are read, the grid's
axes, the tuning search, which scenarios are ranked). Nothing in a table is written by hand: a key added to a spec
appears on the next generation, and ``tests/test_study_reference.py`` checks that the committed reference is this
module's output and lists every key of every spec the parser meets.

Run ``python -m jointbench.benchmarks.study_reference [docs/study_yaml.md]`` to regenerate it.

The tables are :mod:`benchmarks.schema_tables`'s; each names its spec in a comment (``<!-- schema: module.Class
-->``), so that the reference can be checked against the parser (:func:`benchmarks.schema_tables.documented`).
"""
from __future__ import annotations

import dataclasses
import re
import sys
from pathlib import Path

from jointbench.benchmarks.schema_tables import (Section, anchor_of, first_paragraph, render_section, units_table,
                                                 value_text, with_nested)


#: the reference's place in a checkout
DOC = Path("docs") / "study_yaml.md"
COMMAND = "python -m jointbench.benchmarks.study_reference"


# ------------------------------------------------------------------------------------------ sections
def _names(items) -> str:
    return ", ".join(f"`{n}`" for n in items)


def _builtin(registry, get=None) -> list[str]:
    """The names of a registry whose entries ship with jointbench (a plugin's are documented by the plugin; a
    protocol is known by its function's module)."""
    def module(n):
        obj = registry.get(n)
        return getattr(getattr(obj, "fn", obj), "__module__", "")
    return [n for n in registry.names() if module(n).startswith("jointbench.")]


def _registry_sections(title: str, registry, level: int = 3, spec=lambda cls: cls) -> list[Section]:
    """One section per built-in entry of ``registry`` (``title`` formatted with its name)."""
    return [Section(title.format(name=n), spec(registry.get(n)), level=level, intro=first_paragraph(registry.get(n)))
            for n in _builtin(registry)]


Chapter = tuple[str, list[str], list[Section]]


def _study_chapter() -> Chapter:
    from jointbench.benchmarks import config, published

    return ("study.yaml", [
        "A study is a folder holding `study.yaml` (or any YAML file: `jointbench run path/to/my_study.yaml`). Joint "
        "models named by a string, the published values and plugins are looked up beside the file first (and in "
        "its `models/` folder), then in the package (`configs/models/`)."], [
        Section("The study file", config.StudyFile, notes={
            "parts": {"type": "mapping name -> a part", "link": f"see [A part](#{anchor_of(config.PartFile)})"},
            "published": {"type": "text (a file's path), or none",
                          "link": f"[published.yaml](#{anchor_of(published.PublishedFile)})"}}),
        Section("`readings[]`: a reading of an ambiguous passage", config.Reading,
                intro="Rendered in the report's Interpretation section; a check's `reading` names one by `id`."),
        Section("`not_reproduced[]`: what is left out, and why", config.NotReproduced),
        Section("`method_swap`: the swap test of two methods", config.MethodSwap)])


def _part_chapter() -> Chapter:
    from jointbench import sims
    from jointbench.benchmarks import config, figures, protocols
    from jointbench.benchmarks.compare import grid
    from jointbench.sims.experiment import ExperimentSpec

    notes = {"seeds": {"type": "a count (`7`: seeds 0 to 6) or a list of whole numbers"},
             "protocol": {"allowed": _names(_builtin(protocols.REGISTRY))},
             "backend": {"allowed": _names(sims.BACKENDS.names())},
             "figure": {"allowed": _names(figures.REGISTRY.names())},
             "params": {"link": "the protocol's: [Protocol parameters](#protocol-parameters)"},
             "experiment": {"link": f"[The experiment](#{anchor_of(ExperimentSpec)})"},
             "estimators": {"type": "mapping estimator -> its settings, or none",
                            "link": "[Estimator settings](#estimator-settings)"}}
    for key in (f.name for f in dataclasses.fields(grid.GridSpec)):     # the grid's keys, written in the part
        notes[key] = {"type": "see the grid", "link": f"[The comparison grid](#{anchor_of(grid.GridSpec)})"}
    return ("A part", [
        "`parts: {name: {...}}`: one figure or table of a paper (or one comparison), computed by a protocol on "
        "an experiment, or by protocol `compare` on a comparison grid (the keys `grid`, `scenarios`, "
        "`variations`, `perturbations`, `budget`, `tuning`, `only`). `--set PART.KEY=VALUE` changes any of them "
        "from the command line before the file is checked."], [Section("A part", config.PartFile, notes=notes)])


def _protocols_chapter() -> Chapter:
    from jointbench.benchmarks import protocols
    from jointbench.benchmarks.studies.westwick2012.protocol import Joint as WestwickJoint
    from jointbench.sims.subjects import SubjectDesign

    by_params: dict[type, list[str]] = {}
    for n in _builtin(protocols.REGISTRY):
        by_params.setdefault(protocols.REGISTRY.get(n).Params, []).append(n)
    secs = [Section("Protocol " + _names(names), cls, intro=first_paragraph(protocols.REGISTRY.get(names[0]).fn))
            for cls, names in by_params.items()]
    secs += [Section("`params.joint` of `westwick2012.input_bandlimit` and `westwick2012.sampling_rate`",
                     WestwickJoint, level=4, intro=first_paragraph(WestwickJoint)),
             Section("`params.subjects` of `vanderuit2018.table2`", SubjectDesign, level=4,
                     intro=first_paragraph(SubjectDesign))]
    return ("Protocol parameters", [
        "A part's `params` are its protocol's (`protocol:`); a sweep's keys are parameters too. The protocols a "
        "new study uses are `compare` (a comparison grid) and `parametric_fit`; the others compute one published "
        "figure or table each."], secs)


def _grid_chapter() -> Chapter:
    from jointbench import sims
    from jointbench.benchmarks.compare import grid, protocol as compare, tuning
    from jointbench.sims.experiment import ExperimentSpec

    search = {"type": "mapping estimator -> setting -> list of values"}
    axes = axis_values(grid, sims)
    return ("The comparison grid", grid_rules(grid, compare), [
        Section("The grid's keys (in the part)", grid.GridSpec, notes={
            "variations": {"type": "mapping name -> a profile without its levels", "link": "[Profiles](#profiles)"},
            "perturbations": {"type": "mapping name -> `{kind: NAME, ...}`",
                              "link": f"[perturbations](#{anchor_of(sims.PERTURBATIONS.get('prbs'))})"},
            "tuning": search}),
        Section("`grid`: the axes", grid.GridAxes, intro=axes_text(grid),
                notes={k: {"type": "list", "allowed": v} for k, v in axes.items()}),
        Section("`scenarios.NAME`: a scenario", grid.ScenarioSpec, notes={
            "experiment": {"link": f"[The experiment](#{anchor_of(ExperimentSpec)})"},
            "estimators": {"type": "mapping estimator -> its settings",
                           "link": "[Estimator settings](#estimator-settings)"},
            "tuning": search}),
        Section("`only[]`: a rule running part of the grid", tuning.OnlyRule),
        Section("`when` and `keep` of a rule: axis -> a value or a list", tuning.AxisValues,
                notes={k: {"type": "a value or a list", "allowed": v} for k, v in axes.items()})])


def _experiment_chapter() -> Chapter:
    from jointbench import sims
    from jointbench.sims.apparatus import APPARATUS_KINDS
    from jointbench.sims.experiment import Acquisition, ExperimentSpec
    from jointbench.sims.gravity import Gravity
    from jointbench.sims.joint_position_dependent import AngleSpec
    from jointbench.sims.sensors import AngleSensor, SensorFilter, Sensors, TorqueSensor
    from jointbench.sims.voluntary import Voluntary

    joints = []
    for sec in _registry_sections("`joint: {{model: {name}}}`", sims.JOINTS, level=4):
        joints.append(sec)
        if sec.cls.model == "position_dependent":
            joints.append(Section("`K`, `B` of `position_dependent`: a function of the angle", AngleSpec, level=4,
                                  intro=first_paragraph(AngleSpec)))
    joint = {"type": "mapping `{model: NAME, ...}`, or a model's name", "link": "[Joint models](#joint-models)",
             "allowed": f"`model`: {_names(_builtin(sims.JOINTS))}"}
    return ("The experiment", [
        "A part's `experiment` (or a grid scenario's): the simulated joint, apparatus, perturbation, sensors and "
        "acquisition. `joint` is a model given inline (`{model: time_varying, ...}`) or the name of a file of "
        "`configs/models/` (or of the study's `models/` folder); any joint model takes a `reflex` "
        "(`{pathway: stretch, ...}`). A parameter that can vary in time (a joint's `K`, `B`, `k`, a reflex's "
        "`gain`) is a number or a [profile](#profiles)."], [
        Section("The experiment", ExperimentSpec, notes={"joint": joint}),
        Section("`acquisition`", Acquisition),
        Section("`voluntary`: voluntary torque", Voluntary),
        Section("`sensors`", Sensors),
        Section("`sensors.angle`", AngleSensor),
        Section("`sensors.torque`", TorqueSensor),
        Section("`filter`, `noise_filter`: a sensor's filter", SensorFilter),
        Section("`gravity`: gravity on the limb segment (physics backends)", Gravity),
        *[Section(f"`apparatus: {{kind: {n}}}`", cls, intro=first_paragraph(cls))
          for n, cls in APPARATUS_KINDS.items()],
        *_registry_sections("`perturbation: {{kind: {name}}}`", sims.PERTURBATIONS),
        *joints,
        *_registry_sections("`joint: {{reflex: {{pathway: {name}}}}}`", sims.REFLEXES, level=4)])


def _profiles_chapter() -> Chapter:
    from jointbench import sims

    return ("Profiles", [
        "A time-varying parameter: a plain number (constant) or `{shape: NAME, ...}`. A grid's `variations` are "
        "profiles whose levels the scenario's `stiffness` gives (`mean` and `amplitude`, and `period` for sine "
        "and square; a ramp goes from `mean - amplitude` to `mean + amplitude`). A profile's numbers are plain "
        "(in the unit of the parameter it describes)."], _registry_sections("`{{shape: {name}}}`", sims.PROFILES))


def _estimators_chapter() -> Chapter:
    from jointbench import estimators

    return ("Estimator settings", [
        "A part's `estimators: {name: {setting: value}}` (a grid's: the paper settings, over which a scenario's "
        "`estimators` go). `api.settings(NAME)` lists the same; a plugin's estimators are documented by the "
        "plugin."],
        [Section(f"`{n}`", estimators.REGISTRY.get(n).Settings, intro=estimators.REGISTRY.summary(n))
         for n in _builtin(estimators.REGISTRY)])


def _published_chapter() -> Chapter:
    from jointbench.benchmarks import published

    checks = {"type": "list of checks", "link": f"[a check](#{anchor_of(published.CheckEntry)})"}
    return ("published.yaml", [
        "The published values a study checks, beside `study.yaml` (named by its `published` key). Every check "
        "says what kind of evidence a pass is and why its band is what it is."], [
        Section("The published-values file", published.PublishedFile, notes={"checks": checks}),
        Section("`checks[]`: a check", published.CheckEntry, intro=check_kinds_text(published)),
        Section("A range in `select`, `versus` or `domain`: `{column: {lt: ...}}`", published.Range)])


def sections() -> list[Chapter]:
    """``(chapter, its paragraphs, its sections)`` in the order of the reference."""
    return [_study_chapter(), _part_chapter(), _protocols_chapter(), _grid_chapter(), _experiment_chapter(),
            _profiles_chapter(), _estimators_chapter(), _published_chapter()]


def axis_values(grid, sims) -> dict[str, str]:
    """axis -> the values it takes (from the grid's constants and the registries)."""
    native = f"`{grid.NATIVE}` (the scenario's own)"
    return {"estimator": "registered estimators (`jointbench list`)",
            "scenario": "names of `scenarios` (default: every scenario)",
            "joint": f"{native} or a model of `configs/models/`",
            "variation": f"{native} or names of `variations`",
            "perturbation": f"{native} or names of `perturbations`",
            "noise": "numbers >= 0: var(noise)/var(torque) on the torque channel (0: none)",
            "fs": f"{native} or rates (`100 Hz`)",
            "backend": _names(sims.BACKENDS.names()),
            "data": _names(grid.DATA), "tuning": _names(grid.TUNING)}


def axes_text(grid) -> str:
    return (f"Each axis a non-empty list, each value once; every axis but `estimator` is optional. One case per "
            f"estimator and combination of the axes (each case simulates the scenario's R realizations); a grid "
            f"may have at most {grid.MAX_COMBINATIONS} combinations. A combination an estimator cannot run is "
            f"skipped with the reason; so is one on a backend this installation lacks (`mujoco` without the "
            f"`[mujoco]` extra), the others run.")


#: a small comparison study, shown in the reference (tests/test_study_reference.py loads and expands it)
EXAMPLE = """\
study: my_comparison
title: "SDS and FSEWLS on a time-varying elbow"
paper: none
not_reproduced: []
parts:
  grid:
    protocol: compare
    description: "two methods, sine and square stiffness, two noise levels, paper and tuned settings"
    params: {realizations: 10, discard: 2 s}
    grid:
      estimator: [fsewls, sds]
      variation: [sine, square]
      noise: [0.034, 0.11]
      tuning: [paper, tuned]
    tuning:
      sds: {window: [0.5 s, 1 s, 2 s]}
    variations:
      sine: {shape: sine}
      square: {shape: square}
    scenarios:
      elbow:
        experiment:
          joint: {model: time_varying, I: 0.06, K: 40, damping_ratio: 0.3}
          apparatus: {kind: torque_drive}
          perturbation: {kind: prbs, amplitude: 4, clock: 10 ms}
          fs_sim: 2 kHz
          duration: 30 s
          acquisition: {fs: 200 Hz, trim: 0.5 s}
        stiffness: {mean: 40, amplitude: 15, period: 4 s}
    estimators:
      sds: {window: 1 s, lag_before: 20 ms, lag_after: 20 ms}
"""


def grid_rules(grid, compare) -> list[str]:
    """The rules of a comparison grid that are not one key's: tuning, identifiability and ranking."""
    cp = {f.name: f for f in dataclasses.fields(compare.CompareParams)}
    identify = value_text(cp["identify"].default)
    return [
        "A small comparison study (`jointbench run my_comparison.yaml`):\n\n```yaml\n" + EXAMPLE + "```",
        "A part with `grid` runs protocol `compare` on every combination of its axes: one case per estimator and "
        "combination, each simulating R realizations (`params.realizations`, a scenario's `realizations` over it; "
        f"default {cp['realizations'].default}) scored against the simulated stiffness. "
        f"`budget` (default {grid.DEFAULT_BUDGET_MIN:g} min) refuses a grid estimated to take longer unless "
        "`--yes`.",
        "**Tuning** (axis `tuning: [paper, tuned]`): `paper` runs each method at its settings (`estimators`, a "
        "scenario's `estimators` over the part's); `tuned` chooses among the paper setting and the values of "
        "the part's `tuning` search, `{estimator: {setting: [values]}}` (a scenario's `tuning` over the part's, "
        "setting by setting), e.g. `tuning: {sds: {window: [0.5 s, 1 s, 2 s]}}`: each candidate fitted to tuning "
        f"realizations (indices from {compare.TUNE_OFFSET}, never scored, their truth removed), scored by the "
        f"output VAF of {compare.N_HELD_OUT} other tuning realizations. A method the search names no setting of "
        "is skipped in `tuned` (\"nothing to tune\"); a search for an estimator not on the axis, or with no "
        "`tuned` column, is an error.",
        f"**Identifiability** (`params.identify`, default {identify}): every resolved experiment (the axes but "
        "`estimator`, `data` and `tuning`) gets one case of protocol `identifiability`, rows with estimator "
        "`(scenario)`: the share of the measured torque's variance due to the stiffness and to its time "
        "variation, the noise share and the SNR of the time-varying stiffness torque, from the simulation's truth "
        f"(median over the first {compare.N_IDENTIFY} realizations).",
        "**Which scenarios are ranked**: a scenario (a combination of the axes but estimator, data, tuning and "
        "backend) is ranked only when at least one method's median VAF of the stiffness over realizations is "
        "above 0 % (a constant at the true mean scores exactly 0 %: some method must beat it). Otherwise it is "
        "infeasible: shown with its identifiability figures, left out of every ranking and win count, and the "
        "report says why in one line (no method scored there; or the best VAF with the time-varying torque's "
        "share and SNR; or that `params.identify` is off). Rankings use the analytic backend when it ran (the "
        "others get one agreement line per scenario); ranks are competition ranks among finite values, per "
        "scenario, metric and tuning column.",
    ]


def check_kinds_text(published) -> str:
    kinds = "; ".join(f"`{k}` needs {_names(sorted(needs))} and takes {_names(sorted(allows))}"
                      for k, (needs, allows) in published.CHECK_KINDS.items())
    return (f"Check kinds: {kinds}. Evidence: {_names(published.EVIDENCE)} (the headline counts `reproduction` "
            f"only). `select`, `versus` and `domain` map a column of the tidy rows to a value or a range.")


def reference() -> str:
    """The whole reference (``docs/study_yaml.md``)."""
    chapters = sections()
    known = {s.cls for _, _, secs in chapters for s in secs}
    chapters = [(title, paragraphs, with_nested(secs, known)) for title, paragraphs, secs in chapters]
    lines = ["# Study files: every key", "",
             f"<!-- generated by `{COMMAND}` from the schema; do not edit by hand -->", "",
             "Every key a study file (`study.yaml`) and its published values (`published.yaml`) may hold, as the "
             "parser reads them: its type, unit, default, allowed values and meaning. A key it does not know, a "
             "missing required key or a bad value is an error naming the file, the key and what is allowed; every "
             "error of a file comes at once, one per line (and those found when a grid's combinations are made, before "
             "anything runs).", "",
             "How values are read:", "",
             "- A number with a unit may be given bare (in the unit shown) or as text with any unit of the same "
             "dimension: `5 kHz`, `40 ms`, `0.02 rad`, `30000 N.m/rad`. A key without a unit takes a plain number.",
             "- `none`, `null` or `off` is no value for a key whose type says `or none`; `.inf` is infinity where "
             "allowed.",
             "- A list key takes a single value as a list of one; a `mapping name -> X` maps names you choose to X.",
             "- `{kind: NAME, ...}`, `{model: NAME, ...}`, `{shape: NAME, ...}`, `{pathway: NAME, ...}`: the first "
             "key picks a class, whose own keys follow (tables below).", "",
             *units_table([sec for _, _, secs in chapters for sec in secs]), "", "Contents:", ""]
    lines += [f"- [{title}](#{re.sub(r'[^a-z0-9 -]', '', title.lower()).replace(' ', '-')})"
              for title, _, _ in chapters]
    for title, paragraphs, secs in chapters:
        lines += ["", f"## {title}", ""]
        for p in paragraphs:
            lines += [p, ""]
        for i, s in enumerate(secs):
            if title == "The experiment" and s.level == 4 and (i == 0 or secs[i - 1].level != 4):
                lines += ['<a id="joint-models"></a>', "", "### Joint models", ""]
            if s.cls.__name__ == "GridAxes":
                lines += ['<a id="the-axes"></a>', ""]
            lines += render_section(s)
    return "\n".join(line.rstrip() for line in lines).rstrip() + "\n"


def main(argv: list[str] | None = None) -> int:
    args = sys.argv[1:] if argv is None else argv
    path = Path(args[0]) if args else DOC
    text = reference()
    changed = not path.is_file() or path.read_text() != text
    if changed:
        path.write_text(text)
    print(f"{path}: {'rewritten' if changed else 'already up to date'}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
