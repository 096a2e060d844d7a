"""docs/study_yaml.md, the reference of a study's files, is generated from the schema (benchmarks/study_reference.py):
the committed file is the generator's output, and it lists exactly the keys of every spec the parser reads a study
file with, found here independently of the generator: the specs named by every ``parse(...)`` call of the package
(read from its source), the registries' classes, the specs nested in their fields, and the specs the parser meets
while loading and expanding every shipped study."""
from __future__ import annotations

import ast
import dataclasses
import importlib
import typing

import pytest

from jointbench.benchmarks import study_reference as ref
from jointbench.benchmarks.schema_tables import documented as documented_in, qualified
from tests.harness_studies import REPO

#: specs parse() reads that are not a study's files (the nightly run's config, configs/nightly.yaml)
NOT_STUDY_FILES = {"jointbench.benchmarks.nightly.NightlyFile"}
#: the package's folders and their module prefixes
PACKAGES = {"jointbench": "jointbench", "sims": "jointbench.sims", "estimators": "jointbench.estimators",
            "benchmarks": "jointbench.benchmarks"}


def test_the_committed_reference_is_the_generators_output():
    """Regenerate with `python -m jointbench.benchmarks.study_reference` after changing a spec."""
    assert (REPO / ref.DOC).read_text() == ref.reference()


def _parsed_in_source() -> set[type]:
    """The dataclasses named as the first argument of a ``parse(...)`` call in the package's source."""
    found = set()
    for folder, prefix in PACKAGES.items():
        for path in sorted((REPO / folder).rglob("*.py")):
            rel = path.relative_to(REPO / folder).with_suffix("")
            parts = [p for p in rel.parts if p != "__init__"]
            name = ".".join([prefix, *parts])
            tree = ast.parse(path.read_text())
            calls = [n for n in ast.walk(tree) if isinstance(n, ast.Call) and n.args
                     and getattr(n.func, "id", getattr(n.func, "attr", None)) == "parse"
                     and isinstance(n.args[0], ast.Name)]
            if not calls:
                continue
            module = importlib.import_module(name)
            for call in calls:
                cls = getattr(module, call.args[0].id, None)
                if dataclasses.is_dataclass(cls):
                    found.add(cls)
    return found


def _registered() -> set[type]:
    """The specs of the registries' built-in entries (a plugin registered by another test documents its own)."""
    from jointbench import estimators, sims
    from jointbench.benchmarks import protocols
    from jointbench.sims.apparatus import APPARATUS_KINDS

    def builtin(reg, get=None):        # a protocol is known by its function's module
        return [(get or reg.get)(n) for n in reg.names()
                if getattr(getattr(reg.get(n), "fn", reg.get(n)), "__module__", "").startswith("jointbench.")]

    out = set(builtin(protocols.REGISTRY, lambda n: protocols.REGISTRY.get(n).Params))
    out |= set(builtin(estimators.REGISTRY, lambda n: estimators.REGISTRY.get(n).Settings))
    for reg in (sims.JOINTS, sims.PERTURBATIONS, sims.PROFILES, sims.REFLEXES):
        out |= set(builtin(reg))
    return out | set(APPARATUS_KINDS.values())


def _met_loading_the_shipped_studies(monkeypatch) -> set[type]:
    """The specs :func:`jointbench.core.schema.parse` reads while every shipped study is loaded and expanded."""
    from jointbench.benchmarks.config import load_study
    from jointbench.benchmarks.locate import study_ids
    from jointbench.benchmarks.runner import expand_study
    from jointbench.core import schema

    seen, hints = set(), schema._hints

    def recording(cls):
        seen.add(cls)
        return hints(cls)

    monkeypatch.setattr(schema, "_hints", recording)
    for sid in study_ids():
        expand_study(load_study(sid))
    return seen


def _with_nested(classes: set[type]) -> set[type]:
    """The classes and every dataclass their fields hold (in their types or as their default factories)."""
    out, todo = set(), list(classes)
    while todo:
        cls = todo.pop()
        if cls in out:
            continue
        out.add(cls)
        for f in dataclasses.fields(cls):
            tp = typing.get_type_hints(cls)[f.name]
            stack = [tp]
            while stack:
                t = stack.pop()
                if dataclasses.is_dataclass(t) and isinstance(t, type):
                    todo.append(t)
                stack += [a for a in typing.get_args(t) if a is not Ellipsis]
            if dataclasses.is_dataclass(f.default_factory):
                todo.append(f.default_factory)
    return out


def test_the_reference_lists_every_key_the_parser_accepts(monkeypatch):
    specs = {c for c in _parsed_in_source() | _registered() | _met_loading_the_shipped_studies(monkeypatch)
             if qualified(c) not in NOT_STUDY_FILES}
    specs = _with_nested(specs)
    assert len(specs) > 60                                    # the study file, parts, grids, experiments, ...
    documented = documented_in((REPO / ref.DOC).read_text())
    missing = sorted(qualified(c) for c in specs if qualified(c) not in documented)
    assert not missing, f"specs the parser reads that docs/study_yaml.md leaves out: {missing}"
    for cls in specs:
        keys = [f.name for f in dataclasses.fields(cls) if f.init]
        assert documented[qualified(cls)] == keys, qualified(cls)
    stale = sorted(set(documented) - {qualified(c) for c in specs})
    assert not stale, f"sections of specs the parser does not read: {stale}"


@pytest.mark.parametrize("key, text", [
    ("identify", "| `identify` | true or false |  | true |"),
    ("case_time_limit", "| `case_time_limit` | number | s | 600 | > 0 s; `.inf` allowed |"),
    ("ramp duration", "| `duration` | number | s | **required** | > 0 s | time the ramp takes |"),
])
def test_a_row_gives_type_unit_default_and_allowed_values(key, text):
    assert text in (REPO / ref.DOC).read_text(), key


def test_the_reference_says_which_scenarios_are_ranked_and_how_tuning_is_written():
    text = (REPO / ref.DOC).read_text()
    assert "**Which scenarios are ranked**" in text and "above 0 %" in text
    assert "tuning: {sds: {window: [0.5 s, 1 s, 2 s]}}" in text
    assert "`joint: {model: time_varying}`" in text


def test_the_generator_rewrites_only_a_changed_file(tmp_path, capsys):
    out = tmp_path / "study_yaml.md"
    assert ref.main([str(out)]) == 0 and out.read_text() == ref.reference()
    assert ref.main([str(out)]) == 0 and "already up to date" in capsys.readouterr().out


def test_the_example_study_of_the_reference_loads_and_expands(tmp_path):
    """The example shown in docs/study_yaml.md is a valid study: loaded, its cases made (none run)."""
    from jointbench.benchmarks.config import load_study
    from jointbench.benchmarks.runner import expand_study

    assert "```yaml\n" + ref.EXAMPLE + "```" in (REPO / ref.DOC).read_text()
    path = tmp_path / "my_comparison.yaml"
    path.write_text(ref.EXAMPLE)
    cases, skipped = expand_study(load_study(path))
    compare = [c for c in cases if c.protocol == "compare"]
    assert {c.sweep["estimator"] for c in compare} == {"fsewls", "sds"}
    assert sum(c.protocol == "identifiability" for c in cases) == 4            # identify: on by default
    assert all(s["tuning"] == "tuned" and "nothing to tune" in s["reason"] for s in skipped)
