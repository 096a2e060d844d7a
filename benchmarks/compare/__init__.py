"""Method comparison grids: every estimator on every scenario, scored against the truth, ranked and tested.

A study part with a ``grid:`` key (:mod:`.grid`: the grid's spec and its expansion; :mod:`.tuning`: the
tuning search and the ``only`` rules) runs protocol ``compare`` (:mod:`.protocol`: one estimator on one
scenario, R realizations; and ``identifiability``, :mod:`.identifiability`). Its report
(:mod:`.figures`) is drawn from the tidy rows: the full table and ranks (:mod:`.tables`), paired
comparisons (:mod:`.pairs`, statistics in :mod:`.stats`), figures (:mod:`.plots`) and the interactive page
(:mod:`.page`). ``compare`` here always means this: methods against each other. A study's values against
the published ones are its *checks* (:mod:`benchmarks.checks`); one run against another is a *diff*
(:mod:`benchmarks.harness.diff`).
"""
