"""JointBench core: the small set of shared data types at the bottom of the dependency graph.

``sims``, ``estimators`` and ``benchmarks`` all import from here; this package imports none of them.
"""
from jointbench.errors import ConfigError, InputError, JointBenchError
from jointbench.types import Trial, Truth

__all__ = ["ConfigError", "InputError", "JointBenchError", "Trial", "Truth"]
__version__ = "0.1.0"
