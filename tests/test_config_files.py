"""Study files a careless user or a hostile one writes: encodings, resource bombs, devices, ``published:``
and reserved study ids; each is one line naming the file, before anything runs (issue 20)."""
from __future__ import annotations

import os
import re
import time
from pathlib import Path

import pytest
import yaml

from jointbench.benchmarks.config import MAX_YAML_DEPTH, load_study
from jointbench.core.errors import ConfigError
from tests.harness_studies import cli_here as cli, tiny_study


def _refused(path, words: str) -> str:
    with pytest.raises(ConfigError) as exc:
        load_study(path)
    msg = str(exc.value)
    assert str(path) in msg and re.search(words, msg) and "\n" not in msg, msg
    return msg


def _text(tmp_path) -> str:
    return tiny_study(tmp_path / "cfg").read_text().replace("Tiny test study", "Tiny study of Müller")


@pytest.mark.parametrize("encoding, words", [
    ("latin-1", r"not UTF-8 text: byte 0xfc at line \d+, column \d+; save the file as UTF-8"),
    ("utf-16", r"the file is UTF-16 text \(it starts with a UTF-16 byte-order mark\); save it as UTF-8"),
    ("utf-16-le", r"not UTF-8 text \(it looks like UTF-16\)"),
])
def test_a_study_file_that_is_not_utf8_is_one_line(tmp_path, encoding, words):
    path = tmp_path / "s.yaml"
    path.write_bytes(_text(tmp_path).encode(encoding))
    _refused(path, words)


def test_a_utf8_byte_order_mark_is_accepted(tmp_path):
    path = tmp_path / "s.yaml"
    path.write_bytes(b"\xef\xbb\xbf" + _text(tmp_path).encode())
    assert load_study(path).title == "Tiny study of Müller tiny"


def test_an_alias_bomb_is_refused_before_anything_is_built(tmp_path):
    """Nine levels of nine aliases: 387 million values once expanded (the description would be their text)."""
    bomb = "a: &a [x, x, x, x, x, x, x, x, x]\n" + "".join(
        f"{c}: &{c} [{', '.join('*' + p for _ in range(9))}]\n" for p, c in zip("abcdefgh", "bcdefghi"))
    data = yaml.safe_load(_text(tmp_path))
    text = yaml.safe_dump(data, sort_keys=False).replace("description: second-order fit on filtered noise",
                                                         "description: *i")
    path = tmp_path / "s.yaml"
    path.write_text("bomb:\n" + "".join("  " + ln + "\n" for ln in bomb.splitlines()) + text)
    t0 = time.process_time()
    _refused(path, r"expands to more than 500000 values \(aliases of anchors that hold aliases: an alias bomb\?\)")
    assert time.process_time() - t0 < 30


@pytest.mark.parametrize("nested", ["[" * 20000 + "]" * 20000, "{a: " * 5000 + "1" + "}" * 5000,
                                    "\n" + "".join(" " * i + f"k{i}:\n" for i in range(1, 3000)) + " " * 3000 + "v: 1"])
def test_deeply_nested_yaml_is_one_line_not_a_recursion_error(tmp_path, nested):
    path = tmp_path / "s.yaml"
    path.write_text(f"study: {nested}\n")
    _refused(path, rf"collections nested more than {MAX_YAML_DEPTH} deep")


def test_a_50_mb_study_file_is_refused_before_it_is_parsed(tmp_path):
    path = tmp_path / "s.yaml"
    path.write_text(_text(tmp_path) + "# " + "x" * 50_000_000 + "\n")
    _refused(path, r"is 50 MB, more than the 10 MB allowed for a config file")


@pytest.mark.parametrize("make, words", [
    (lambda p: os.symlink("/dev/zero", p), "is a device, not a regular file"),
    (lambda p: os.mkfifo(p), r"is a FIFO \(named pipe\), not a regular file"),
    (lambda p: p.mkdir(), "is a folder, not a file"),
])
def test_a_study_file_that_is_not_a_regular_file_is_refused_without_reading_it(tmp_path, make, words):
    path = tmp_path / "s.yaml"
    make(path)
    _refused(path, words)


def test_yaml_syntax_errors_are_one_line_with_the_place(tmp_path):
    path = tmp_path / "s.yaml"
    path.write_text("study: x\n\tparts: {}\n")
    _refused(path, r"not valid YAML: line 2, column 1: .*found character '\\t' that cannot start any token")


@pytest.mark.parametrize("value", [123, ["a.yaml", "b.yaml"], {"x": 1}, None, True, ""])
def test_published_must_be_a_path(tmp_path, value):
    path = tiny_study(tmp_path / "cfg")
    data = yaml.safe_load(path.read_text())
    data["published"] = value
    path.write_text(yaml.safe_dump(data))
    _refused(path, r"key 'published': expected the path of the published values")


def test_published_checks_must_be_a_list(tmp_path):
    path = tiny_study(tmp_path / "cfg")
    pub = tmp_path / "cfg" / "tiny_published.yaml"
    pub.write_text("study: tiny\nsource: x\nchecks: 5\n")
    with pytest.raises(ConfigError, match=r"tiny_published\.yaml: key 'checks': expected a list of checks, got 5"):
        load_study(path)


@pytest.mark.parametrize("study_id", ["cache", "nightly", "history.sqlite", "Cache", "NIGHTLY"])
def test_reserved_study_ids_are_refused(tmp_path, study_id):
    path = tiny_study(tmp_path / "cfg", study=study_id)
    r = cli("run", path, "--out", tmp_path / "out", "--quiet")
    assert r.returncode == 2 and r.stderr.count("\n") == 1, r.stderr
    assert f"key 'study': {study_id!r} is a reserved name of the results folder" in r.stderr
    assert not (tmp_path / "out").exists()          # refused before any folder is made


def test_a_results_folder_that_is_a_symlink_loop_is_one_line(tmp_path):
    os.symlink("loop", tmp_path / "loop")
    r = cli("run", tiny_study(tmp_path / "cfg"), "--out", tmp_path / "loop", "--quiet")
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and "Traceback" not in r.stderr, r.stderr


def test_status_of_a_missing_results_folder_is_an_error(tmp_path):
    r = cli("status", "--results", tmp_path / "nope")
    assert r.returncode == 2 and "no such folder" in r.stderr


def test_the_fast_reader_gives_the_reference_reader_s_documents():
    """Configs are read with libyaml's C parser when PyYAML has it (benchmarks/config_yaml.py); every
    shipped config must give the document of the pure-Python reference reader, and a refusal is the
    reference reader's (its message, as the tests above check)."""
    import yaml

    from jointbench.benchmarks import config_yaml as cy

    if cy.FastStrictLoader is cy.StrictLoader:
        pytest.skip("PyYAML without libyaml: only the reference reader")
    repo = Path(__file__).resolve().parents[1]
    paths = sorted([*(repo / "configs").rglob("*.yaml"), *(repo / "benchmarks" / "studies").rglob("*.yaml")])
    assert len(paths) > 10
    for p in paths:
        text = p.read_text(encoding="utf-8-sig")
        assert yaml.load(text, Loader=cy.FastStrictLoader) == yaml.load(text, Loader=cy.StrictLoader), p
    with pytest.raises(cy._DuplicateKey, match="line 3: duplicate key 'a' .first given on line 1"):
        yaml.load("a: 1\nb: 2\na: 3\n", Loader=cy.FastStrictLoader)
