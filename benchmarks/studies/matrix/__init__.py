"""Study ``matrix``: The comparison matrix: every estimator on every scenario of the three papers, paper and tuned
settings (a comparison grid, protocol ``compare``, no published values).

Here: ``published.yaml``, ``study.yaml`` (``jointbench run matrix``; results in ``results/matrix/``).
"""
