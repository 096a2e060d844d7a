"""Dependencies flow one way: jointbench <- {sims, estimators} <- benchmarks (CLI on top)."""
import ast
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
FORBIDDEN = {
    "jointbench": {"sims", "estimators", "benchmarks"},
    "sims": {"estimators", "benchmarks"},
    "estimators": {"sims", "benchmarks"},
}


def imported_modules(path: Path) -> set[str]:
    """Every module ``path`` imports, in full (``from a.b import c`` gives ``a.b`` and ``a.b.c``: c may be
    a module); relative imports resolved against the file's package."""
    tree = ast.parse(path.read_text(), str(path))
    package = ".".join(path.relative_to(REPO).with_suffix("").parts[:-1])
    out = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out |= {a.name for a in node.names}
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                parent = package.rsplit(".", node.level - 1)[0] if node.level > 1 else package
                base = f"{parent}.{base}" if base else parent
            out.add(base)
            out |= {f"{base}.{a.name}" for a in node.names}
    return out


def imported_top_levels(path: Path) -> set[str]:
    return {m.split(".")[0] for m in imported_modules(path) if m}


@pytest.mark.parametrize("package", sorted(FORBIDDEN))
def test_layering(package):
    bad = []
    for f in sorted((REPO / package).rglob("*.py")):
        hit = imported_top_levels(f) & FORBIDDEN[package]
        if hit:
            bad.append(f"{f.relative_to(REPO)} imports {sorted(hit)}")
    assert not bad, "\n".join(bad)


def test_recordings_need_only_the_core():
    """benchmarks/recordings (``jointbench estimate``) imports jointbench and estimators, nothing else of the
    project: not the rest of benchmarks (harness, protocols, figures, config), not sims."""
    room = REPO / "benchmarks" / "recordings"
    files = sorted(room.rglob("*.py"))
    assert files, room
    inside = ("benchmarks", "benchmarks.recordings")  # the package itself and this room

    def outside(m: str) -> bool:
        top = m.split(".")[0]
        return top == "sims" or (top == "benchmarks" and m not in inside and not m.startswith(inside[1] + "."))

    bad = []
    for f in files:
        hit = sorted(filter(outside, imported_modules(f)))
        if hit:
            bad.append(f"{f.relative_to(REPO)} imports {hit}")
    assert not bad, "\n".join(bad)


def test_runtime_never_reads_shared():
    """../shared exists only beside developers' checkouts: code outside tests must not refer to it."""
    for pkg in ("jointbench", "sims", "estimators", "benchmarks"):
        for f in (REPO / pkg).rglob("*.py"):
            assert "shared/data" not in f.read_text(), f"{f} refers to ../shared"


def test_modules_stay_small():
    big = [f"{f.relative_to(REPO)}: {n}" for pkg in ("jointbench", "sims", "estimators", "benchmarks")
           for f in (REPO / pkg).rglob("*.py") if (n := len(f.read_text().splitlines())) > 500]
    assert not big, big


def test_estimator_index_matches_the_registry():
    """The registry knows the estimators from their source (``jointbench estimate --list`` imports none
    of them); importing every module must register exactly those names, tags and summaries."""
    import estimators

    known = {n: (estimators.REGISTRY.tags(n), estimators.REGISTRY.summary(n)) for n in estimators.REGISTRY.names()}
    estimators.import_all()
    loaded = {n: (estimators.REGISTRY._tags[n], (estimators.REGISTRY._items[n].__doc__ or "").strip().splitlines()[0])
              for n in estimators.REGISTRY._items}
    assert known == loaded
