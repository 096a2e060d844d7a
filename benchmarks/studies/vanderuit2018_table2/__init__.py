"""Study ``vanderuit2018_table2``: van de Ruit et al. (2018), Table II: single-trial KBR and skirt against
ensembles of 5 (KBR, skirt, SDS, Guarin, ensemble IRF) on six simulated subjects of the 0.05 Hz torque task.

Here: ``figures.py``, ``protocol.py``, ``published.yaml``, ``study.yaml`` (``jointbench run
vanderuit2018_table2``; results in ``results/vanderuit2018_table2/``).
"""
