"""Study ``lpv``: K(theta) from one trial with a slow movement: ``pv_irf`` against FSEWLS's K-hat(t) mapped through
theta (Sobhani Tehrani & Kearney 2022; Xu & Hollerbach 1998; a comparison study).

Here: ``figures.py``, ``protocol.py``, ``published.yaml``, ``study.yaml`` (``jointbench run lpv``; results in
``results/lpv/``).
"""
