"""Study ``westwick2012``: Westwick & Perreault (2012), *Estimates of acausal joint impedance models*: discrete
differentiators, sampling rate, input bandwidth and noise; two-sided IRFs, spectral and parametric fits (ankle,
elbow).

Here: ``figures.py``, ``protocol.py``, ``published.yaml``, ``study.yaml`` (``jointbench run westwick2012``;
results in ``results/westwick2012/``).
"""
