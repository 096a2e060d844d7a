"""The simulator's registries: name -> class for joint models, perturbations, backends, profiles and reflexes.

They live in a module of their own, which imports nothing of ``jointbench.sims``, so that the modules that
register into them (``@JOINTS.register("second_order")``) or look a name up in them
(:class:`~jointbench.sims.experiment.Experiment`) import them from here and never the package itself:
the package's ``__init__`` imports every submodule (so that the registries are complete), and a submodule
importing the package back was an import loop. ``jointbench.sims`` re-exports each registry under its
old name (``jointbench.sims.JOINTS`` is :data:`JOINTS`), for users and plugins.
"""
from __future__ import annotations

from jointbench.core.registry import Registry

#: joint models (``sims/joint_*.py``): the limb's intrinsic dynamics, e.g. ``second_order``
JOINTS = Registry("joint model")
#: perturbations (``sims/perturbation_*.py``): the drive signals, e.g. ``prbs``, ``multisine``
PERTURBATIONS = Registry("perturbation")
#: simulation backends (``sims/backend_*.py``): how the dynamics are integrated, e.g. ``analytic``, ``mujoco``
BACKENDS = Registry("simulation backend")
#: time-variation profiles (``sims/profile*.py``): how a parameter changes over the record, e.g. ``ramp``
PROFILES = Registry("time-variation profile")
#: reflex pathways (``sims/reflex_*.py``): feedback from the stretch of the muscle, e.g. ``stretch``
REFLEXES = Registry("reflex pathway")

__all__ = ["BACKENDS", "JOINTS", "PERTURBATIONS", "PROFILES", "REFLEXES"]
