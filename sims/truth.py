"""The truth of a simulated trial: the joint's parameters at the acquired samples, the frozen transfer
function, and the noise-free signals of the nonlinear parts (reflex torque, scheduling variable).

Used by :func:`sims.simulate` once the response is acquired; a function of the experiment and the
response only.
"""
from __future__ import annotations

import numpy as np

from jointbench.core.types import Truth


def truth(exp, signals: dict[str, np.ndarray], angle: np.ndarray | None = None) -> Truth:
    """Parameters at the acquired sample times and the frozen input -> output transfer function.

    A joint whose coefficients depend on its state (``state_coefficients``, e.g. K(theta)) states them
    along the simulated ``angle`` (at the simulation rate), read at the acquired sample times."""
    t = exp.acquired_times()
    if angle is not None and getattr(exp.joint, "nonlinear", False) and hasattr(exp.joint, "state_coefficients"):
        I, B, K = exp.joint.state_coefficients(np.interp(t, np.arange(len(angle)) / exp.fs_sim, angle))
    else:
        I, B, K = exp.joint.coefficients_at(t)
    Z = np.column_stack([I, B, K])
    if exp.joint.time_invariant:
        I, B, K = float(I[0]), float(B[0]), float(K[0])
        Z = Z[:1]
    num, den = exp.apparatus.coupling(exp.joint).frozen_response(Z, exp.apparatus.imposed,
                                                                 exp.apparatus.angle_is_drive)
    if exp.joint.time_invariant:
        num, den = num[0], den[0]
    return Truth(I=I, B=B, K=K, signals=signals, num=num, den=den)


def part_signals(exp, names: list[str], filtered: np.ndarray) -> dict[str, np.ndarray]:
    """The truth's signals of the nonlinear parts: the response's torque parts (``names``; their columns
    of ``filtered``, through the torque sensor's filter at the simulation rate) acquired like the torque;
    the perturbation's own truth signals (the ``scheduling`` variable of a slow movement) and the reflex
    gain, at the acquired sample times."""
    out: dict[str, np.ndarray] = {}
    if names:
        acquired = exp.acquire(filtered)
        out.update({k: np.ascontiguousarray(acquired[:, i]) for i, k in enumerate(names)})
    t = exp.acquired_times()
    if hasattr(exp.perturbation, "truth_signals"):
        out.update(exp.perturbation.truth_signals(t))
    if getattr(exp, "reflex", None) is not None:
        out["reflex_gain"] = exp.reflex.gain_at(t)
    return out
