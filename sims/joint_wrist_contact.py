"""Joint model ``wrist_contact``: intrinsic wrist (I, b, k(t)) held through a visco-elastic hand contact.

``I theta'' + b theta' + k(t) theta = y`` with the handle torque ``y = b_c (u' - theta') + k_c (u - theta)``
for handle angle ``u``. Use it with the apparatus ``handle`` (the handle angle is imposed and measured,
the handle torque measured). The frozen transfer from u to y is
``(b_c s + k_c)(I s² + b s + k(t)) / (I s² + (b + b_c) s + k(t) + k_c)``.
"""
from __future__ import annotations

import dataclasses
import math
from typing import Any, ClassVar

import numpy as np

from jointbench.core.errors import ConfigError
from jointbench.core.schema import Problems, param
from jointbench.sims.registries import JOINTS
from jointbench.sims.profile import parse_profile_fields, require_positive


@JOINTS.register("wrist_contact", tags=("ltv", "contact"))
@dataclasses.dataclass(frozen=True)
class WristContactJoint:
    """Wrist with time-varying intrinsic stiffness and a hand-handle contact.

    YAML: ``{model: wrist_contact, I: 3 g.m2, b: 0.035, k: {shape: square, mean: 5.6, amplitude: 0.9,
    period: 20 s}, b_c: 10, k_c: 100}``.

    Parameters
    ----------
    I : float
        Inertia (kg·m²), > 0.
    b : float
        Intrinsic damping (N·m·s/rad), >= 0.
    k : float or profile
        Intrinsic stiffness (N·m/rad), must stay > 0.
    b_c, k_c : float
        Contact damping (N·m·s/rad) and stiffness (N·m/rad), > 0.

    References
    ----------
    van de Ruit et al. 2018, eqs. 11-13 (Sec. IV-B): I = 3 g·m², b = 0.035, b_c = 10, k_c = 100.
    """

    I: float = param(unit="kg.m2", gt=0, doc="inertia")
    b: float = param(unit="N.m.s/rad", ge=0, doc="intrinsic damping")
    k: Any = dataclasses.field(metadata={"doc": "intrinsic stiffness: number or profile"})
    b_c: float = param(10.0, unit="N.m.s/rad", gt=0, doc="contact damping")
    k_c: float = param(100.0, unit="N.m/rad", gt=0, doc="contact stiffness")

    model: ClassVar[str] = "wrist_contact"

    def __post_init__(self):
        problems = Problems()                      # every error of the model at once
        with problems.catch():
            if self.k is None:
                raise ConfigError("missing required key 'k'")
            parse_profile_fields(self, ("k",))
            require_positive("k", self.k, strict=True)
        for name in ("I", "b", "b_c", "k_c"):
            if not math.isfinite(getattr(self, name)):
                problems.add(ConfigError(f"key '{name}': must be finite"))
        problems.raise_all()

    @property
    def contact(self) -> tuple[float, float]:
        """``(k_c, b_c)``: contact stiffness and damping."""
        return float(self.k_c), float(self.b_c)

    @property
    def time_invariant(self) -> bool:
        return self.k.constant

    def coefficients_at(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Intrinsic ``(I, b, k)`` at times ``t`` (s), as arrays shaped like ``t``."""
        t = np.asarray(t, float)
        return np.full(t.shape, float(self.I)), np.full(t.shape, float(self.b)), self.k.at(t)
