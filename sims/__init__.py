"""Simulators: descriptions of experiments (joint models, perturbations, apparatus, sensors) kept
apart from the backends that integrate them. One file per joint model, perturbation or backend,
registered by decorator in a registry of :mod:`jointbench.sims.registries`. Installed as
``jointbench.sims`` (the repository's ``sims/`` folder); it imports the core of ``jointbench`` only, never
``jointbench.estimators`` or ``jointbench.benchmarks``.

Importing it loads every submodule (so that the registries are complete) but no physics engine: the
``mujoco`` backend registers itself and imports ``mujoco`` and ``dm_control`` only when it first builds
a model, so ``import jointbench.sims`` neither needs nor loads them (tests/test_backend_mujoco.py checks it).
"""
from __future__ import annotations

from jointbench.core.registry import import_submodules

# The registries are defined in sims/registries.py (which imports nothing of the package, so that the modules
# that register into them import them from there, never this package) and re-exported here under their
# names, `jointbench.sims.JOINTS` and the others, for users and plugins.
from jointbench.sims.registries import BACKENDS, JOINTS, PERTURBATIONS, PROFILES, REFLEXES

# Every submodule, so that the registries are complete; `simulate` and `Experiment` are defined in
# sims/experiment.py and re-exported here.
import_submodules(__name__, __path__)

from jointbench.sims.experiment import Experiment, simulate  # noqa: E402

__all__ = ["BACKENDS", "Experiment", "JOINTS", "PERTURBATIONS", "PROFILES", "REFLEXES", "simulate"]
