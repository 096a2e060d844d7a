"""The user's fitting path, beneath the API: a recorded angle and torque in, a checked impedance estimate out.

Read the records (:mod:`.read`, :mod:`.read_ensemble`, limits checked before loading in
:mod:`.read_limits`; a scheduling channel in :mod:`.schedule`), check and crop them (:mod:`.checks`), fit
and score (:mod:`.pipeline`), and draw the estimate (:mod:`.plots`). ``jointbench estimate``
(:mod:`jointbench.cli.estimate`) and :func:`jointbench.api.fit` both come here. It imports the core and
``jointbench.estimators`` only: never the harness or the simulators (tests/test_architecture.py). Kept
empty so that ``jointbench estimate --list`` stays quick.
"""
