"""Study ``xu1998``: Xu & Hollerbach (1998), *Identification of human joint mechanical properties from single trial
data*: FSEWLS on a time-varying elbow (Figs. 2-3, the calibration arm, candidate readings).

Here: ``figures.py``, ``protocol.py``, ``published.yaml``, ``study.yaml`` (``jointbench run xu1998``; results in
``results/xu1998/``).
"""
