"""docs/architecture.md's two walks name modules and functions that exist, and walk the floors down and back
up, never climbing from a lower floor to call a higher one (a doc that runs as a test)."""
import ast
import re
from pathlib import Path

import pytest

from tests.test_architecture import FLOORS, REPO, module_of_file, room_of

DOC = REPO / "docs" / "architecture.md"


def walks() -> dict[str, list[tuple[list[Path], list[str]]]]:
    """Walk title -> its steps: (the files named in the module cell, the functions named in the next cell)."""
    out: dict[str, list] = {}
    title = None
    for line in DOC.read_text().splitlines():
        if line.startswith("## Walk"):
            title = line[3:]
            out[title] = []
        elif title and re.match(r"\| \d+ \|", line):
            cells = [c.strip() for c in line.strip("|").split("|")]
            files = [REPO / name for name in re.findall(r"`([\w/]+\.py)`", cells[1])]
            out[title].append((files, re.findall(r"`([\w.]+)`", cells[2])))
    return out


def _defined(path: Path) -> set[str]:
    tree = ast.parse(path.read_text())
    names = set()
    for node in ast.walk(tree):
        if isinstance(node, (ast.FunctionDef, ast.ClassDef)):
            names.add(node.name)
            if isinstance(node, ast.ClassDef):
                names |= {f"{node.name}.{n.name}" for n in node.body if isinstance(n, ast.FunctionDef)}
    return names


@pytest.mark.parametrize("title", sorted(walks()))
def test_the_walk_names_what_exists(title):
    steps = walks()[title]
    assert len(steps) >= 8, title
    for files, functions in steps:
        assert files and all(f.is_file() for f in files), files
        defined = set().union(*(_defined(f) for f in files))
        missing = [fn for fn in functions if fn.split("(")[0] not in defined]
        assert not missing, f"{[str(f.relative_to(REPO)) for f in files]}: {missing} not defined there"


@pytest.mark.parametrize("title", sorted(walks()))
def test_the_walk_goes_down_then_back_up(title):
    """The floors along a walk fall to the lowest and rise back: a step to a higher floor before the lowest
    is reached would be a climb back up (a lower floor calling a higher one)."""
    floors = [min(FLOORS[room_of(module_of_file(f))] for f in files) for files, _ in walks()[title]]
    low = floors.index(min(floors))
    assert floors[:low + 1] == sorted(floors[:low + 1], reverse=True), floors
    assert floors[low:] == sorted(floors[low:]), floors
