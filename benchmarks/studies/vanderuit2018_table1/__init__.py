"""Study ``vanderuit2018_table1``: van de Ruit et al. (2018), *Revealing time-varying joint impedance with kernel-
based regression and nonparametric decomposition*: skirt decomposition and KBR on the wrist with hand contact
(Table I, Figs. 3, 4, 7(b)/8(a)).

Here: ``figures.py``, ``generate_checks.py``, ``protocol.py``, ``published.yaml``, ``study.yaml`` (``jointbench
run vanderuit2018_table1``; results in ``results/vanderuit2018_table1/``).
"""
