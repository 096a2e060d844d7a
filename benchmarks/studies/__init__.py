"""The shipped studies: one folder each, with everything that is one study's own.

``<id>/study.yaml`` (its parts, the readings of ambiguous passages, what it does not reproduce),
``<id>/published.yaml`` (the published values it is checked against: bands, kinds of evidence, sources),
``<id>/protocol.py`` (what one case computes, registered by name) and ``<id>/figures.py`` (its figures and
tables, drawn from the tidy rows), where the study has code of its own. What several studies share lives
beside this folder: the joint models (``configs/models/``), the generic protocol and figure
(:mod:`benchmarks.protocols.generic`, :mod:`benchmarks.figures.generic`) and the method comparison grids
(:mod:`benchmarks.compare`). A study of one's own is a ``study.yaml`` anywhere (or a folder holding one):
``jointbench run path/to/my_study.yaml`` (:mod:`benchmarks.locate`).
"""
from __future__ import annotations

from pathlib import Path


def modules(kind: str) -> list[tuple[str, Path]]:
    """``(module name, source file)`` of every study's ``kind`` module (``"protocol"`` or ``"figures"``), for
    the registries: nothing is imported."""
    return [(f"{__name__}.{p.parent.name}.{kind}", p) for p in sorted(Path(__path__[0]).glob(f"*/{kind}.py"))]
