"""The harness machinery: how cases run, are cached and remembered, and how runs are compared.

A newcomer's map (everything a study *computes* lives in ``benchmarks/protocols``; how it is *drawn*
in ``benchmarks/figures`` and ``benchmarks/report.py``):

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
- :mod:`~benchmarks.harness.compare`: what changed between two runs (checks, metrics, timings).
- :mod:`~benchmarks.harness.nightly`, :mod:`~benchmarks.harness.nightly_pages` and :mod:`~benchmarks.harness.pages`:
  what ``jointbench nightly`` (:mod:`benchmarks.nightly`) counts as a regression, and its static HTML
  pages (Jinja2 templates in ``templates/``).
"""
