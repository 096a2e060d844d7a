"""Simulators: descriptions of experiments (joint models, perturbations, apparatus, sensors) kept
apart from the backends that integrate them. One file per joint model, perturbation or backend,
registered by decorator. This package imports ``jointbench`` only, never ``estimators`` or
``benchmarks``.
"""
from __future__ import annotations

from jointbench.registry import Registry, import_submodules

JOINTS = Registry("joint model")
PERTURBATIONS = Registry("perturbation")
BACKENDS = Registry("simulation backend")
PROFILES = Registry("time-variation profile")

# `simulate` and `Experiment` are defined in sims/experiment.py and re-exported here.
import_submodules(__name__, __path__)

from sims.experiment import Experiment, simulate  # noqa: E402

__all__ = ["BACKENDS", "Experiment", "JOINTS", "PERTURBATIONS", "PROFILES", "simulate"]
