"""The harness: configs, runner, metrics, tables, comparison with published values, reports, CLI.

Installed as ``jointbench.benchmarks``. It imports the core, ``jointbench.sims`` and ``jointbench.estimators``;
nothing imports it but the CLI and tests.
``recordings/`` (the ``jointbench estimate`` path) needs only ``jointbench`` and ``estimators``.
"""
