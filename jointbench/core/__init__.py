"""The bottom floor: what every other part of JointBench stands on, and which imports nothing above it.

The data types (:mod:`.types`: ``Trial``, ``Truth``; :mod:`.ensemble`; the estimates of :mod:`.estimate` and
:mod:`.estimate_tv`), the errors meant for a person (:mod:`.errors`), strict settings (:mod:`.schema`), the
registries filled by decorators (:mod:`.registry`) and the outside estimators that fill them
(:mod:`.plugins`), signal processing shared by simulators and estimators (:mod:`.signal`,
:mod:`.differentiators`), and safe file writing (:mod:`.files`). The floors above it: ``jointbench.sims`` and
``jointbench.estimators``; the user's fitting path (:mod:`jointbench.fitting`); the harness
(``jointbench.benchmarks``); the Python API (:mod:`jointbench.api`); the command line (:mod:`jointbench.cli`).
tests/test_architecture.py keeps the floors.
"""
