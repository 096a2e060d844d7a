"""The shipped configs, as package data of ``jointbench`` (``jointbench.configs``): study configs
(``studies/``), joint models (``models/``), published values (``published/``) and ``nightly.yaml``.

Nothing is imported from here: :mod:`jointbench.benchmarks.locate` finds the folder with
:func:`importlib.resources.files`, so that a study runs the same from an installed wheel as from a checkout.
"""
