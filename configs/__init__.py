"""The shipped configs the studies share, as package data of ``jointbench`` (``jointbench.configs``): the joint
models (``models/``: a study or an experiment names one with ``joint: <name>``) and ``nightly.yaml`` (what
``jointbench nightly`` runs and what counts as a regression). Each study's own ``study.yaml`` and
``published.yaml`` live in its folder, ``benchmarks/studies/<id>/``.

Nothing is imported from here: :mod:`jointbench.benchmarks.locate` finds the folder with
:func:`importlib.resources.files`, so that a study runs the same from an installed wheel as from a checkout.
"""
