"""The harness machinery: how cases run, are cached and remembered, and what changed between runs.

A newcomer's map (everything a study *computes* lives in its ``protocol.py``, ``benchmarks/studies/<id>/``;
how it is *drawn* in its ``figures.py`` and ``benchmarks/report.py``):

- :mod:`~benchmarks.harness.case`: one case (a JSON-serialisable spec) and ``run_case``, the only code
  that computes numbers; its import closure is what the cache key hashes.
- :mod:`~benchmarks.harness.fingerprint`: that closure, the code hash, versions, machine and git state.
- :mod:`~benchmarks.harness.cache`: finished cases on disk, keyed by everything that can change a number
  and verified on read.
- :mod:`~benchmarks.harness.pool`: the executors (serial, a process pool whose workers die with their
  parent and ignore Ctrl-C); any ``concurrent.futures``-style executor plugs in.
- :mod:`~benchmarks.harness.outputs`: where results go (``results/<study>``, checked and locked).
- :mod:`~benchmarks.harness.history`: every run in ``results/history.sqlite`` (SQLite, WAL,
  transactional).
- :mod:`~benchmarks.harness.diff`: what changed between two runs (checks, metrics, timings):
  ``jointbench diff``.
- :mod:`~benchmarks.harness.pages` and :mod:`~benchmarks.harness.nightly_pages`: the report model and the
  static HTML pages (Jinja2 templates in ``templates/``) of a study and of ``jointbench nightly``
  (:mod:`benchmarks.nightly`).
"""
