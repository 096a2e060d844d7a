"""Study ``realdata``: every estimator that fits a single recorded trial, scored by two-fold cross-validated output
VAF on REKLAB's five stationary ankle trials (no truth; the data fetched on demand: ``jointbench data fetch
reklab``).

Here: ``figures.py``, ``protocol.py``, ``study.yaml`` (``jointbench run realdata``).
"""
