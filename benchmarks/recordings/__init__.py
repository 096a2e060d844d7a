"""The recordings path: a user's own recorded angle and torque in, an impedance estimate out.

Reading records (:mod:`.io`, :mod:`.io_ensemble`), checking and cropping them (:mod:`.checks`), the
``jointbench estimate`` command (:mod:`.cli`) and its figure (:mod:`.plots`). It imports only the core
(``jointbench``) and ``estimators``; never the harness, ``sims``, the protocols or the figures
(tests/test_architecture.py). Kept empty so that ``jointbench estimate --list`` stays quick.
"""
