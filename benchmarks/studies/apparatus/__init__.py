"""Study ``apparatus``: Apparatus effects only a physics backend simulates (MuJoCo): the servo stiffness argument
of Westwick & Perreault (2012, eqs. 3-8) and gravity on Xu & Hollerbach's elbow (1998, eqs. 1-2).

Here: ``figures.py``, ``protocol.py``, ``published.yaml``, ``study.yaml`` (``jointbench run apparatus``; results
in ``results/apparatus/``).
"""
