"""MJCF models of the joint models and their apparatus, generated in code with ``dm_control.mjcf``.

Three models, all from the same joint-model and apparatus objects as the analytic backends (so both
describe the same system), all hinges about z:

- **limb on a torque drive** (``torque_drive``; Xu & Hollerbach's elbow): forearm and hand on a hinge,
  the perturbation torque and the voluntary torque as ``motor`` actuators, gravity optional;
- **limb behind a position servo** (``position_servo``; Westwick & Perreault's Fig. 1): the same limb,
  the servo as a ``general`` actuator with an affine bias, ``T_a = u - K_a theta - B_a theta'``, whose
  input ``u = K_a theta_r + B_a theta_r'`` is the coupling's drive input: the finite servo gain K_a;
- **wrist with handle and contact** (``handle``; van de Ruit et al.'s eqs. 11-13): the hand on the wrist
  hinge and the handle on its own hinge, nested in the hand's body so that its joint coordinate is the
  contact deflection delta = u - theta; the contact is a fixed tendon on delta with stiffness k_c and
  damping b_c (an exact linear spring-damper), and a second fixed tendon u = theta + delta carries the
  handle's position servo (``general`` actuator, affine bias on u and u'). Nesting puts both joints in
  one kinematic tree: MuJoCo's implicit integrators keep the off-diagonal terms of a tendon's damping
  only inside a tree (with the handle as a second tree the stiff contact damping is integrated half
  explicitly and the hand lags the handle by about one step: torque VAF 99.89 % instead of 99.99 %).

The limb's own K(t) and B(t) are inputs, applied every step: ``general`` actuators with an affine gain,
force = -K(t) theta (gainprm = [0, -1, 0], control K(t)) and -B(t) theta' (gainprm = [0, 0, -1],
control B(t)). The damping's velocity gain is integrated implicitly by ``implicitfast``; stiffness never
is (see :mod:`sims.backend_mujoco` for the step it allows).

Only ``dm_control.mjcf`` builds the model; it is compiled with ``mujoco.MjModel.from_xml_string`` (see
:mod:`sims.backend_mujoco` for why not ``mjcf.Physics``). dm_control is imported on first use.

References
----------
Westwick & Perreault 2012, Fig. 1; Xu & Hollerbach 1998, eqs. 1 and 7; van de Ruit et al. 2018,
eqs. 11-13; MuJoCo documentation, XML reference (general actuator, fixed tendon) and "Numerical
integration" (implicitfast).
"""
from __future__ import annotations

import dataclasses
import os

import numpy as np

from jointbench.core.errors import ConfigError

#: the control columns of each model, in actuator order
CONTROLS = {
    "torque_drive": ("stiffness", "damping", "drive", "voluntary"),
    "position_servo": ("stiffness", "damping", "drive", "voluntary"),
    "handle": ("stiffness", "damping", "handle_servo", "voluntary"),
}

#: the handle of an ideal-handle experiment, as the physics backend realizes it: a 0.01 kg·m² handle on
#: a critically damped servo whose natural frequency is HANDLE_BANDWIDTH_STEPS / step (1250 rad/s,
#: 199 Hz, at 2.5 kHz), with velocity and acceleration feed-forward of the drive signal
IDEAL_HANDLE_INERTIA = 0.01
HANDLE_BANDWIDTH_STEPS = 0.5


def mjcf_module():
    """``dm_control.mjcf``, imported without an OpenGL renderer (the models are never drawn)."""
    os.environ.setdefault("MUJOCO_GL", "disable")
    try:
        from dm_control import mjcf
    except ImportError as exc:  # pragma: no cover - depends on the installation
        raise ConfigError(f"backend 'mujoco' needs the packages mujoco and dm-control "
                          f"(pip install 'jointbench[mujoco]'): {exc}") from None
    return mjcf


@dataclasses.dataclass(frozen=True)
class HandleServo:
    """The handle's own dynamics in the physics model: inertia (kg·m²), servo stiffness and damping."""

    inertia: float
    stiffness: float
    damping: float

    @classmethod
    def of(cls, apparatus, timestep: float) -> "HandleServo":
        """The configured handle, or the stand-in for an ideal one (see :data:`IDEAL_HANDLE_INERTIA`)."""
        if apparatus.inertia is not None:
            return cls(apparatus.inertia, apparatus.servo_stiffness, apparatus.servo_damping)
        w = HANDLE_BANDWIDTH_STEPS / timestep
        return cls(IDEAL_HANDLE_INERTIA, IDEAL_HANDLE_INERTIA * w * w, 2.0 * IDEAL_HANDLE_INERTIA * w)


def _limb_body(parent, name: str, inertia: float, gravity):
    """A segment on a hinge about z, extending along +x: its inertial matches ``inertia`` about the hinge
    (a point mass at the centre of mass plus the rest as rotational inertia); massless visual geoms (the
    forearm and the hand; contacts are off)."""
    body = parent.add("body", name=name)
    joint = body.add("joint", name=f"{name}_joint", type="hinge", axis=[0, 0, 1])
    if gravity is not None:
        m, l = gravity.mass, gravity.com_distance
        own = inertia - m * l * l
        body.add("inertial", pos=[l, 0, 0], mass=m, diaginertia=[own, own, own])
        length = 2.0 * l
    else:
        body.add("inertial", pos=[0, 0, 0], mass=1.0, diaginertia=[inertia] * 3)
        length = 0.3
    body.add("geom", name=f"{name}_geom", type="capsule", fromto=[0, 0, 0, length, 0, 0], size=[0.03],
             contype=0, conaffinity=0, mass=0)
    if name == "forearm":   # the hand at the end of the forearm, one rigid segment with it
        body.add("geom", name="hand_geom", type="box", pos=[length + 0.06, 0, 0], size=[0.06, 0.04, 0.015],
                 contype=0, conaffinity=0, mass=0)
    return body, joint


def _limb_actuators(root, joint) -> None:
    """K(t) and B(t) of the joint as inputs: force = -K theta and -B theta' (affine gains)."""
    root.actuator.add("general", name="stiffness", joint=joint, gaintype="affine", gainprm=[0, -1, 0],
                      ctrllimited=False)
    root.actuator.add("general", name="damping", joint=joint, gaintype="affine", gainprm=[0, 0, -1],
                      ctrllimited=False)


def build(joint, apparatus, gravity, timestep: float, integrator: str = "implicitfast"):
    """The MJCF model (a ``dm_control.mjcf.RootElement``) of ``joint`` held by ``apparatus``.

    Parameters
    ----------
    joint : joint model
        ``second_order``, ``time_varying`` (torque drive or position servo) or ``wrist_contact``
        (handle); its inertia must be constant.
    apparatus : PositionServo, TorqueDrive or Handle
        How the drive acts on the limb.
    gravity : Gravity or None
        Gravity on the segment (a rotated gravity vector: theta = 0 lies ``posture`` from straight down).
    timestep : float
        Integration step (s).
    integrator : str
        MuJoCo integrator (default ``implicitfast``: implicit in the velocity gains of the damping
        actuators and in tendon damping).

    Raises
    ------
    ConfigError
        A joint model or apparatus this backend cannot build, or a varying inertia.
    """
    kind = apparatus.kind
    contact = getattr(joint, "contact", None)
    if kind not in CONTROLS or (kind == "handle") != (contact is not None):
        raise ConfigError(f"backend 'mujoco' cannot build joint model '{getattr(joint, 'model', joint)}' with "
                          f"apparatus '{kind}'; it builds a joint without contact on a torque_drive or "
                          f"position_servo, and a joint with a contact (wrist_contact) on a handle")
    I = np.asarray(joint.coefficients_at(np.linspace(0.0, 1.0, 5))[0], float)
    if np.ptp(I) > 0:
        raise ConfigError(f"backend 'mujoco' needs a constant inertia, joint model '{joint.model}' varies it")
    inertia = float(I[0])
    mjcf = mjcf_module()
    root = mjcf.RootElement(model={"torque_drive": "limb_torque_drive", "position_servo": "limb_position_servo",
                                   "handle": "wrist_handle"}[kind])
    root.option.timestep = timestep
    root.option.integrator = integrator
    if gravity is None:
        root.option.gravity = [0, 0, 0]
    else:   # "down" makes the angle `posture` with the segment at theta = 0 (along +x)
        root.option.gravity = [gravity.g * np.cos(gravity.posture), -gravity.g * np.sin(gravity.posture), 0.0]
    root.option.flag.contact = "disable"
    name = "hand" if kind == "handle" else "forearm"
    body, limb = _limb_body(root.worldbody, name, inertia, gravity)
    _limb_actuators(root, limb)
    if kind == "handle":
        k_c, b_c = contact
        servo = HandleServo.of(apparatus, timestep)
        handle = body.add("body", name="handle")
        delta = handle.add("joint", name="contact_deflection", type="hinge", axis=[0, 0, 1])
        handle.add("inertial", pos=[0, 0, 0], mass=0.5, diaginertia=[servo.inertia] * 3)
        handle.add("geom", name="handle_geom", type="cylinder", fromto=[0, 0, -0.06, 0, 0, 0.06], size=[0.015],
                   contype=0, conaffinity=0, mass=0)
        contact_tendon = root.tendon.add("fixed", name="contact", stiffness=k_c, damping=b_c)
        contact_tendon.add("joint", joint=delta, coef=1.0)
        u = root.tendon.add("fixed", name="handle_angle")
        u.add("joint", joint=limb, coef=1.0)
        u.add("joint", joint=delta, coef=1.0)
        root.actuator.add("general", name="handle_servo", tendon=u, gainprm=[1], biastype="affine",
                          biasprm=[0, -servo.stiffness, -servo.damping], ctrllimited=False)
        root.sensor.add("tendonpos", name="handle_angle", tendon=u)
    else:
        c = apparatus.coupling(joint)
        if kind == "torque_drive":
            root.actuator.add("motor", name="drive", joint=limb, gear=[1], ctrllimited=False)
        else:
            root.actuator.add("general", name="drive", joint=limb, gainprm=[1], biastype="affine",
                              biasprm=[0, -c.k_a, -c.b_a], ctrllimited=False)
        root.sensor.add("actuatorfrc", name="torque", actuator="drive")
    root.actuator.add("motor", name="voluntary", joint=limb, gear=[1], ctrllimited=False)
    root.sensor.add("jointpos", name="angle", joint=limb)
    return root
