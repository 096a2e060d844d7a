"""The harness: configs, runner, metrics, tables, comparison with published values, reports, CLI.

It imports ``jointbench``, ``sims`` and ``estimators``; nothing imports it but the CLI and tests.
``recordings/`` (the ``jointbench estimate`` path) needs only ``jointbench`` and ``estimators``.
"""
