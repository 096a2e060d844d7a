"""Study ``reflex``: Every stiffness estimator against an unmodelled stretch reflex (Kearney, Stein & Parameswaran
1997; Mirbagheri et al. 2000), and the parallel cascades' separation of the pathways (a comparison study).

Here: ``figures.py``, ``protocol.py``, ``published.yaml``, ``study.yaml`` (``jointbench run reflex``; results in
``results/reflex/``).
"""
