"""The harness (floor 4): studies in, tidy results, checks against the published values and reports out.

Installed as ``jointbench.benchmarks``. It imports the floors beneath it (the core, ``jointbench.sims``,
``jointbench.estimators``, ``jointbench.fitting``); only the API and the command line import it.

- ``studies/<id>/``: one folder per shipped study (``study.yaml``, ``published.yaml``, ``protocol.py``,
  ``figures.py``); :mod:`.locate` finds them, :mod:`.config` parses a study, :mod:`.overrides` its ``--set``;
- :mod:`.runner` expands a study into cases and runs them (the machinery in ``harness/``: case, code hash,
  cache, executors, history); :mod:`.study` runs a whole study and writes its outputs;
- :mod:`.protocols` (what a case computes) and :mod:`.figures` (how a part is drawn): their registries and
  the generic ones; :mod:`.metrics` and :mod:`.scoring`: what a case scores an estimate with;
- :mod:`.tables` (the tidy rows and curves), :mod:`.checks` (the rows judged against the published values),
  :mod:`.report` and :mod:`.status` (the report and the README's status block);
- ``compare/``: method comparison grids (methods against each other);
- :mod:`.nightly`: every study against the published values and the last nightly.
"""
