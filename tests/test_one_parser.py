"""One config parser (issue 34): every config mapping is read by :func:`jointbench.core.schema.parse` of a typed
spec, and every error of a file is reported at once.

The scan below fails when a module outside ``jointbench/core/schema.py`` checks the keys of a mapping by hand:
a table of allowed keys (a module-level ``..._KEYS``), a set difference or comparison of a mapping's keys
against a collection written in the code (a literal, or a module constant), or an "unknown key" message
of its own. Its own test shows it catches planted examples of each.
"""
from __future__ import annotations

import ast
import dataclasses
import re
from pathlib import Path

import pytest
import yaml

from jointbench.benchmarks.config import load_study
from jointbench.benchmarks.nightly import load_config
from jointbench.core.errors import ConfigError
from jointbench.core.schema import param, parse

REPO = Path(__file__).resolve().parents[1]
#: the code folders scanned, and the one module allowed to check keys
CODE = ("jointbench", "sims", "estimators", "benchmarks")
SCHEMA = REPO / "jointbench" / "core" / "schema.py"
_KEY_TABLE = re.compile(r"^_?[A-Z0-9_]*KEYS$")
_CONSTANT = re.compile(r"^_?[A-Z][A-Z0-9_]*$")


def _is_constant_collection(node: ast.AST) -> bool:
    """A collection written in the code: a literal of strings, a module constant (``ALLOWED``), or
    ``set(...)``/``frozenset(...)``/``tuple(...)`` of one."""
    if isinstance(node, (ast.Set, ast.List, ast.Tuple)):
        return bool(node.elts) and all(isinstance(e, ast.Constant) and isinstance(e.value, str) for e in node.elts)
    if isinstance(node, ast.Dict):
        return bool(node.keys) and all(isinstance(k, ast.Constant) and isinstance(k.value, str) for k in node.keys)
    if isinstance(node, ast.Name):
        return bool(_CONSTANT.match(node.id))
    if isinstance(node, ast.Attribute):
        return bool(_CONSTANT.match(node.attr))
    if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id in ("set", "frozenset", "tuple"):
        return len(node.args) == 1 and _is_constant_collection(node.args[0])
    return False


def _is_keys_of_mapping(node: ast.AST) -> bool:
    """``set(x)``, ``x.keys()`` or ``set(x.keys())``: the keys of a mapping read from input."""
    if isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute) and node.func.attr == "keys":
        return True
    if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id in ("set", "frozenset"):
        return len(node.args) == 1 and not _is_constant_collection(node.args[0])
    return False


def hand_key_checks(source: str, name: str = "<source>") -> list[str]:
    """Where ``source`` checks the keys of a mapping by hand (``name:line: what``)."""
    found = []
    for node in ast.walk(ast.parse(source)):
        where = f"{name}:{getattr(node, 'lineno', 0)}"
        if isinstance(node, (ast.Assign, ast.AnnAssign)):
            targets = node.targets if isinstance(node, ast.Assign) else [node.target]
            for t in targets:
                if isinstance(t, ast.Name) and _KEY_TABLE.match(t.id):
                    found.append(f"{where}: a table of keys {t.id}")
        elif isinstance(node, ast.BinOp) and isinstance(node.op, ast.Sub):
            if _is_keys_of_mapping(node.left) and _is_constant_collection(node.right):
                found.append(f"{where}: the keys of a mapping minus a collection of allowed keys")
        elif isinstance(node, ast.Compare) and len(node.comparators) == 1 and \
                isinstance(node.ops[0], (ast.Eq, ast.NotEq)):     # keys == {"polynomial"}
            sides = (node.left, node.comparators[0])
            if any(isinstance(s, ast.Set) and _is_constant_collection(s) for s in sides) and \
                    any(isinstance(s, ast.Name) and "key" in s.id.lower() for s in sides):
                found.append(f"{where}: the keys of a mapping compared with a set of keys")
        elif isinstance(node, ast.Constant) and isinstance(node.value, str) and "unknown key" in node.value.lower():
            found.append(f"{where}: an 'unknown key' message of its own")
    return found


def code_files() -> list[Path]:
    return sorted(p for d in CODE for p in (REPO / d).rglob("*.py") if p != SCHEMA)


def test_no_module_outside_the_schema_checks_keys_by_hand():
    found = [hit for f in code_files() for hit in hand_key_checks(f.read_text(), str(f.relative_to(REPO)))]
    assert not found, "\n".join(found)


@pytest.mark.parametrize("planted", [
    '_PART_KEYS = {"protocol": True, "description": True}\n',
    'STUDY_KEYS = ("study", "title")\n',
    'def check(data):\n    unknown = sorted(set(data) - {"a", "b"})\n',
    'ALLOWED = ("a", "b")\n\ndef check(data):\n    return set(data) - set(ALLOWED)\n',
    'def check(data):\n    return data.keys() - self.ALLOWED\n',
    'def check(data):\n    keys = set(data)\n    return keys == {"polynomial"}\n',
    'def check(data, where):\n    raise ValueError(f"{where}: unknown key {data!r}")\n',
])
def test_the_scan_catches_a_hand_key_check(planted):
    assert hand_key_checks(planted), planted


@pytest.mark.parametrize("clean", [
    'def diff(old, new):\n    return sorted(set(old) - set(new))\n',      # two mappings read at run time
    'x = {"a": 1}\nnames = set(x)\n',
    'def f(spec):\n    return spec.parse(Spec, data, where)\n',
])
def test_the_scan_lets_other_code_be(clean):
    assert not hand_key_checks(clean), clean


# --------------------------------------------------------------------------------- every error at once
@dataclasses.dataclass(frozen=True)
class _Rate:
    rate: float = param(1.0, unit="Hz", gt=0)


def test_one_error_keeps_its_one_line_message():
    with pytest.raises(ConfigError) as exc:
        parse(_Rate, {"rate": "-2 Hz"}, "f.yaml: block")
    assert str(exc.value) == "f.yaml: block: key 'rate': must be > 0 Hz, got -2.0 Hz"
    with pytest.raises(ConfigError) as exc:
        parse(_Rate, {"rat": 1}, "f.yaml: block")
    assert str(exc.value) == "f.yaml: block: unknown key 'rat'; allowed: rate"


@dataclasses.dataclass(frozen=True)
class _Inner:
    n: int = param(1, ge=1)


@dataclasses.dataclass(frozen=True)
class _Outer:
    name: str
    inner: _Inner = dataclasses.field(default_factory=_Inner)
    items: tuple[_Inner, ...] = ()
    mode: bool = False


def test_every_error_of_nested_specs_is_listed_one_per_line():
    with pytest.raises(ConfigError) as exc:
        parse(_Outer, {"title": "x", "inner": {"n": 0, "m": 1}, "items": [{"n": 2}, {"n": "two"}], "mode": "perhaps"},
              "f.yaml")
    assert str(exc.value).splitlines() == [
        "f.yaml: unknown key 'title'; allowed: name, inner, items, mode",   # unknown keys, then field by field
        "f.yaml: missing required key 'name'",
        "f.yaml: inner: unknown key 'm'; allowed: n",
        "f.yaml: inner: key 'n': must be >= 1, got 0",
        "f.yaml: items[1]: key 'n': expected a whole number, got 'two'",
        "f.yaml: key 'mode': expected true or false, got 'perhaps'",
    ]


_STUDY = """
study: many
title: several bad keys
paper: none
not_reproduced: []
colour: red
parts:
  one:
    protocol: parametric_fit
    description: a part
    seeds: 0
    report_section: appendix
    sweeep: {a: [1]}
  two:
    protocol: parametric_fit
    description: another
    backend: bullet
"""


def test_a_study_with_several_bad_keys_reports_all_of_them(tmp_path):
    path = tmp_path / "many.yaml"
    path.write_text(_STUDY)
    with pytest.raises(ConfigError) as exc:
        load_study(path)
    lines = str(exc.value).splitlines()
    assert all(line.startswith(f"{path}: ") for line in lines), lines
    expected = ["unknown key 'colour'; allowed: study, title",
                "parts.one: unknown key 'sweeep'; allowed: protocol, description",
                "parts.one: key 'seeds': need at least 1 seed",
                "parts.one: key 'report_section': 'appendix' not allowed; allowed: results, interpretation",
                "parts.two: key 'backend': unknown simulation backend 'bullet'; known: analytic"]
    assert len(lines) == len(expected), lines
    for words, line in zip(expected, lines):
        assert words in line, (words, line)


def test_a_nightly_config_with_several_bad_keys_reports_all_of_them(tmp_path):
    path = tmp_path / "n.yaml"
    path.write_text(yaml.safe_dump({"studies": ["xu1998"], "use_cache": "maybe", "colour": "red",
                                    "thresholds": [{"metric": "*", "abs": -1, "rel": 0.1, "absolute": 1}]}))
    with pytest.raises(ConfigError) as exc:
        load_config(path)
    assert str(exc.value).splitlines() == [
        f"{path}: unknown key 'colour'; allowed: studies, exclude, use_cache, thresholds, timing, key_checks, "
        f"wall_clock",
        f"{path}: key 'use_cache': expected true or false, got 'maybe'",
        f"{path}: thresholds[0]: unknown key 'absolute'; allowed: metric, abs, rel",
        f"{path}: thresholds[0]: key 'abs': must be >= 0, got -1.0",
    ]


def test_an_experiment_with_several_bad_keys_reports_all_of_them():
    from jointbench.sims.experiment import Experiment

    with pytest.raises(ConfigError) as exc:
        Experiment.from_mapping({"joint": {"model": "second_order", "I": 0.01, "B": 1, "K": 50, "Q": 1},
                                 "perturbation": {"kind": "nope"}, "fs_sim": "1 kHz", "duraton": 2}, "exp")
    assert str(exc.value).splitlines() == [
        "exp: unknown key 'duraton'; allowed: joint, apparatus, perturbation, voluntary, sensors, fs_sim, duration, "
        "acquisition, gravity (a misspelt 'duration', which is missing?)",
        "exp: joint: unknown key 'Q'; allowed: I, B, K",
        f"exp: perturbation: key 'kind': unknown perturbation 'nope'; known: "
        f"{', '.join(__import__('jointbench.sims', fromlist=['PERTURBATIONS']).PERTURBATIONS.names())}",
    ]


def test_several_errors_of_a_spec_checked_on_construction_each_name_where():
    """A profile is parsed when its joint is constructed (``__post_init__``): its several errors still come one
    per line, each line naming where (the catalogue's 'several errors in one profile' found the first line
    alone did)."""
    from jointbench.sims.experiment import Experiment

    with pytest.raises(ConfigError) as exc:
        Experiment.from_mapping({"joint": {"model": "time_varying", "I": 0.01, "B": 0.5,
                                           "K": {"shape": "ramp", "end": 80, "tilt": 1}},
                                 "fs_sim": "1 kHz", "duration": 2}, "exp")
    lines = str(exc.value).splitlines()
    profile = [line for line in lines if not line.startswith("exp: missing required key 'perturbation'")]
    assert all(line.startswith("exp: joint: key 'K' (ramp): ") for line in profile), lines
    assert len(profile) == 5 and sum("unknown key" in line for line in profile) == 2        # end, tilt


def test_a_misspelt_required_key_is_one_error_and_an_empty_file_one_line(tmp_path):
    with pytest.raises(ConfigError) as exc:
        parse(_Outer, {"nmae": "x"}, "f.yaml")
    assert str(exc.value) == ("f.yaml: unknown key 'nmae'; allowed: name, inner, items, mode "
                              "(a misspelt 'name', which is missing?)")
    with pytest.raises(ConfigError) as exc:             # not a misspelling of a missing key: two errors
        parse(_Outer, {"colour": "x"}, "f.yaml")
    assert str(exc.value).splitlines() == ["f.yaml: unknown key 'colour'; allowed: name, inner, items, mode",
                                           "f.yaml: missing required key 'name'"]
    empty = tmp_path / "empty.yaml"
    empty.write_text("")
    for load in (load_study, load_config):
        with pytest.raises(ConfigError) as exc:
            load(empty)
        assert str(exc.value) == f"{empty}: the file is empty; expected a mapping of settings"
