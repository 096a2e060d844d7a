"""JointBench: identify time-varying joint impedance, and benchmark the methods that do it.

One installed namespace, its floors from the ground up (each imports only the floors below it; one room
never imports another room of its own floor; tests/test_architecture.py keeps it so):

1. :mod:`jointbench.core`: the data types, errors, strict settings, registries, plugins, signal helpers;
2. ``jointbench.sims`` (the repository's ``sims/``: simulated experiments) and ``jointbench.estimators``
   (``estimators/``: one file per method);
3. :mod:`jointbench.fitting`: the user's fitting path (read records, check them, fit, score);
4. ``jointbench.benchmarks`` (``benchmarks/``: the harness: studies, cases, checks, reports);
5. :mod:`jointbench.api`: the Python API;
6. :mod:`jointbench.cli`: the command line ``jointbench``.

``docs/architecture.md`` walks a study case and a user's record through them.
"""
from jointbench.core.errors import ConfigError, InputError, JointBenchError
from jointbench.core.types import Trial, Truth

__all__ = ["ConfigError", "InputError", "JointBenchError", "Trial", "Truth"]
__version__ = "0.1.0"
