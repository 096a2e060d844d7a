"""Study ``lpv``: K(theta) from one trial with a slow movement: ``pv_irf`` against FSEWLS's K-hat(t) mapped through
theta (part ``kmap``), and with a stretch reflex the parameter-varying parallel cascade ``pv_parallel_cascade``
against both (part ``reflex``) (Sobhani Tehrani & Kearney 2022; Xu & Hollerbach 1998; a comparison study).

Here: ``figures.py``, ``protocol.py``, ``published.yaml``, ``study.yaml`` (``jointbench run lpv``; results in
``results/lpv/``).
"""
