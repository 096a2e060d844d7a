"""JointBench core: the small set of shared data types at the bottom of the dependency graph.

One installed namespace: the repository's folders ``sims/``, ``estimators/`` and ``benchmarks/`` are the
sub-packages ``jointbench.sims``, ``jointbench.estimators`` and ``jointbench.benchmarks`` (pyproject.toml's
package-dir). They all import from the core modules here; the core imports none of them.
"""
from jointbench.errors import ConfigError, InputError, JointBenchError
from jointbench.types import Trial, Truth

__all__ = ["ConfigError", "InputError", "JointBenchError", "Trial", "Truth"]
__version__ = "0.1.0"
