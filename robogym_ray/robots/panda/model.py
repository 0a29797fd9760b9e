"""Franka Emika Panda and Franka Research 3 (FR3): published parameters, numpy forward
kinematics, and the URDF we load.

The FR3 is a model of this folder rather than a folder of its own: Franka publishes one
Denavit-Hartenberg table for both arms, so kinematics, frames, collision shapes, state layout and
launch options are the Panda's, and only the joint limits (``LIMITS``) differ.

Sources (all published by Franka; nothing is downloaded at run time):

* Kinematics: the Denavit-Hartenberg table of "Robot and interface specifications"
  (frankaemika.github.io/docs/control_parameters.html; frankarobotics.github.io/docs,
  "Control Interface Specification and Robot Limits", for the FR3), in Craig's (modified)
  convention, where the transform from link i-1 to link i is ``Rx(alpha) Tx(a) Rz(theta_i)
  Tz(d)``; the flange (``panda_link8``) is ``d = 0.107`` m beyond joint 7, and ``panda_hand`` is
  the flange turned -pi/4 about z (the hand's mounting).
* Limits: the joint position and velocity limits of the same pages, "Limits for Panda" (also
  robo-gym 2.1.0's ``panda.yaml``) and "Limits for Franka Research 3" (``q_max`` / ``q_min``,
  ``dq_max``). Franka's docs also give the FR3 tighter "rectangular" joint limits, a box in
  which every joint may move whatever the others do. ``FR3_RECTANGULAR`` is the tighter box of
  franka_description's ``robots/fr3/joint_limits.yaml`` (commit 1ddff9b), taken from that file,
  not from the docs' table. Nothing here uses it: the simulated FR3, its card and its envs use
  ``q_min`` ... ``q_max``, the limits at which the robot aborts a motion.

The URDF chain uses the franka_description names ``panda_link0`` ... ``panda_link8``,
``panda_hand``, ``panda_joint1`` ... ``panda_joint7`` for both models (franka_description calls
the FR3's ``fr3_*``; keeping one set of names keeps one state layout and one set of envs); each
joint's ``<origin>`` is the DH row folded into one translation and rotation. Collision geometry
is a capsule or two per link, sized from the published outline drawing (links about 0.11-0.12 m
across), so the usual poses are collision free and folding the hand into the arm or the arm into
the ground collides. The hand and fingers (open, fixed) are collision shapes of ``panda_link8``
so that PyBullet's parent exclusion keeps them from touching link 7 all the time.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from robogym_ray.robots.urdf import cached_urdf

JOINT_NAMES: tuple[str, ...] = tuple(f"panda_joint{i}" for i in range(1, 8))
LINK_NAMES: tuple[str, ...] = tuple(f"panda_link{i}" for i in range(1, 8))
"""The seven moving links (child of each joint); with the hand they carry Gazebo's contact
sensors in robo-gym's Panda server."""

DH: tuple[tuple[float, float, float], ...] = (
    # (a, d, alpha) of joints 1-7, modified DH (Franka's table)
    (0.0, 0.333, 0.0),
    (0.0, 0.0, -math.pi / 2),
    (0.0, 0.316, math.pi / 2),
    (0.0825, 0.0, math.pi / 2),
    (-0.0825, 0.384, -math.pi / 2),
    (0.0, 0.0, math.pi / 2),
    (0.088, 0.0, math.pi / 2),
)
FLANGE_D = 0.107
"""Joint 7 -> flange (``panda_link8``) along z (m)."""
HAND_YAW = -math.pi / 4
"""Flange -> ``panda_hand`` rotation about z (rad)."""

EE_FRAMES: tuple[str, ...] = ("panda_hand", "panda_link8")
"""Frames the ``ee_frame`` launch argument may name, the launch file's default first."""


@dataclass(frozen=True, eq=False)
class ArmLimits:
    """One arm model's joint limits, joints 1-7, as read-only float arrays (sequences given to
    the constructor are copied)."""

    lower: np.ndarray
    """Lowest joint positions (rad)."""
    upper: np.ndarray
    """Highest joint positions (rad)."""
    velocity: np.ndarray
    """Largest joint speeds (rad/s)."""

    def __post_init__(self) -> None:
        for name in ("lower", "upper", "velocity"):
            array = np.array(getattr(self, name), dtype=np.float64).reshape(7)
            array.flags.writeable = False  # shared by every robot and env: no one edits a limit
            object.__setattr__(self, name, array)


PANDA_LIMITS = ArmLimits(
    lower=(-2.8973, -1.7628, -2.8973, -3.0718, -2.8973, -0.0175, -2.8973),
    upper=(2.8973, 1.7628, 2.8973, -0.0698, 2.8973, 3.7525, 2.8973),
    velocity=(2.1750, 2.1750, 2.1750, 2.1750, 2.6100, 2.6100, 2.6100),
)
"""The Panda ("Limits for Panda")."""
FR3_LIMITS = ArmLimits(
    lower=(-2.9007, -1.8361, -2.9007, -3.0770, -2.8763, 0.4398, -3.0508),
    upper=(2.9007, 1.8361, 2.9007, -0.1169, 2.8763, 4.6216, 3.0508),
    velocity=(2.62, 2.62, 2.62, 2.62, 5.26, 4.18, 5.26),
)
"""The FR3 ("Limits for Franka Research 3": ``q_min``, ``q_max``, ``dq_max``)."""
FR3_RECTANGULAR = ArmLimits(
    lower=(-2.7437, -1.7837, -2.9007, -3.0421, -2.8065, 0.5445, -3.0159),
    upper=(2.7437, 1.7837, 2.9007, -0.1518, 2.8065, 4.5169, 3.0159),
    velocity=(2.62, 2.62, 2.62, 2.62, 5.26, 4.18, 5.26),
)
"""The FR3's tighter box of joint positions in franka_description's ``robots/fr3/
joint_limits.yaml`` (commit 1ddff9b); unused (see the module docstring)."""
LIMITS: dict[str, ArmLimits] = {"panda": PANDA_LIMITS, "fr3": FR3_LIMITS}
"""Registry name -> the model's limits: what the simulated arm, its card and its envs use."""
LABELS: dict[str, str] = {"panda": "Panda", "fr3": "FR3"}
"""Registry name -> the model's name in messages."""
LOWER, UPPER, MAX_VELOCITY = PANDA_LIMITS.lower, PANDA_LIMITS.upper, PANDA_LIMITS.velocity
"""The Panda's joint position (rad) and velocity (rad/s) limits, as arrays."""
MAX_EFFORT = (87.0, 87.0, 87.0, 87.0, 12.0, 12.0, 12.0)
"""Joint torque limits (N m) of both models, for the URDF only."""
READY = np.array([0.0, -math.pi / 4, 0.0, -3 * math.pi / 4, 0.0, math.pi / 2, math.pi / 4])
"""The 'ready' pose of franka_ros / libfranka's examples (hand pointing down)."""


# -- kinematics -------------------------------------------------------------------------------
def _rot_x(angle: float) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def rot_z(angle: float) -> np.ndarray:
    """The rotation by ``angle`` (rad) about z."""
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def joint_origin(a: float, d: float, alpha: float) -> tuple[np.ndarray, float]:
    """A DH row as a URDF joint origin: ``(xyz, roll)`` with ``Rx(alpha) Tx(a) Tz(d)`` =
    ``T(xyz) Rx(roll)`` (the rotation about the joint's z axis follows)."""
    return np.array([a, 0.0, 0.0]) + _rot_x(alpha) @ np.array([0.0, 0.0, d]), alpha


def quat_xyzw(r: np.ndarray) -> np.ndarray:
    """Unit quaternion (x, y, z, w), w >= 0, of a rotation matrix."""
    w = math.sqrt(max(0.0, 1.0 + r[0, 0] + r[1, 1] + r[2, 2])) / 2
    x = math.copysign(math.sqrt(max(0.0, 1.0 + r[0, 0] - r[1, 1] - r[2, 2])) / 2, r[2, 1] - r[1, 2])
    y = math.copysign(math.sqrt(max(0.0, 1.0 - r[0, 0] + r[1, 1] - r[2, 2])) / 2, r[0, 2] - r[2, 0])
    z = math.copysign(math.sqrt(max(0.0, 1.0 - r[0, 0] - r[1, 1] + r[2, 2])) / 2, r[1, 0] - r[0, 1])
    q = np.array([x, y, z, w])
    return q / np.linalg.norm(q)


def forward_kinematics(q: np.ndarray | list[float]) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Poses of the link frames in ``panda_link0`` (= robo-gym's ``world``), numpy only.

    Returns:
        ``{frame: (xyz, quat_xyzw)}`` for ``panda_link1`` ... ``panda_link8`` and ``panda_hand``.
    """
    joints = np.asarray(q, dtype=np.float64).reshape(7)
    rot, pos = np.eye(3), np.zeros(3)
    frames: dict[str, tuple[np.ndarray, np.ndarray]] = {}
    for i, ((a, d, alpha), theta) in enumerate(zip(DH, joints, strict=True)):
        xyz, roll = joint_origin(a, d, alpha)
        pos = pos + rot @ xyz
        rot = rot @ _rot_x(roll) @ rot_z(float(theta))
        frames[LINK_NAMES[i]] = (pos.copy(), rot.copy())
    pos = pos + rot @ np.array([0.0, 0.0, FLANGE_D])
    frames["panda_link8"] = (pos.copy(), rot.copy())
    frames["panda_hand"] = (pos.copy(), rot @ rot_z(HAND_YAW))
    return {name: (xyz, quat_xyzw(r)) for name, (xyz, r) in frames.items()}


# -- URDF -------------------------------------------------------------------------------------
Capsule = tuple[float, tuple[float, float, float], tuple[float, float, float]]
"""(radius, end A, end B) of one collision capsule in its link frame."""
Box = tuple[tuple[float, float, float], tuple[float, float, float], float]
"""(half extents, centre, yaw) of one collision box in its link frame."""

CAPSULES: dict[str, list[Capsule]] = {
    "panda_link0": [(0.07, (-0.04, 0.0, 0.05), (0.0, 0.0, 0.12))],
    "panda_link1": [(0.06, (0.0, 0.0, -0.19), (0.0, 0.0, -0.08))],
    "panda_link2": [(0.06, (0.0, 0.0, -0.05), (0.0, 0.0, 0.05)),
                    (0.055, (0.0, -0.07, 0.0), (0.0, -0.15, 0.0))],
    "panda_link3": [(0.055, (0.0, 0.0, -0.14), (0.0, 0.0, -0.03))],
    "panda_link4": [(0.055, (0.0, 0.0, -0.04), (0.0, 0.0, 0.04)),
                    (0.05, (-0.03, 0.06, 0.0), (-0.07, 0.12, 0.0))],
    "panda_link5": [(0.05, (0.0, 0.0, -0.27), (0.0, 0.0, -0.18))],
    "panda_link6": [(0.05, (0.0, 0.0, -0.02), (0.0, 0.0, 0.02))],
    "panda_link7": [(0.04, (0.0, 0.0, 0.0), (0.0, 0.0, 0.07))],
}  # fmt: skip
"""Capsules per link. Link 5's stops 0.18 m below the wrist: the forearm tapers there and the
hand passes beside it at q6 near 0 (the Panda's lower joint-6 limit, -0.0175 rad; the FR3's is
0.4398 rad)."""
HAND_BOXES: list[Box] = [
    ((0.02, 0.09, 0.03), (0.0, 0.0, 0.03), HAND_YAW),
    ((0.01, 0.01, 0.025), (0.0, 0.04, 0.08), HAND_YAW),
    ((0.01, 0.01, 0.025), (0.0, -0.04, 0.08), HAND_YAW),
]
"""The hand (0.04 x 0.18 x 0.06 m) and its two open fingers, in ``panda_link8``'s frame (boxes
are turned with the hand, so the centres are given in the hand's frame and rotated)."""
MASSES = (2.9, 2.7, 2.0, 2.0, 2.4, 1.5, 1.4, 0.5, 0.7)
"""Approximate masses (kg) of link0 ... link7, link8 + hand; the controller is kinematic, so only
plausibility matters (the URDF importer wants inertials)."""


def _fmt(values) -> str:
    return " ".join(f"{float(v):.10g}" for v in values)


def _capsule_xml(radius: float, a, b) -> str:
    a, b = np.asarray(a, float), np.asarray(b, float)
    axis = b - a
    length = float(np.linalg.norm(axis))
    centre = (a + b) / 2
    # Rotate z onto the axis: pitch then yaw (URDF rpy: Rz(yaw) Ry(pitch)).
    pitch = math.atan2(math.hypot(axis[0], axis[1]), axis[2])
    yaw = math.atan2(axis[1], axis[0])
    return (
        f'    <collision><origin xyz="{_fmt(centre)}" rpy="0 {pitch:.10g} {yaw:.10g}"/>'
        f'<geometry><capsule radius="{radius}" length="{length:.10g}"/></geometry></collision>'
    )


def _box_xml(half, centre, yaw: float) -> str:
    xyz = rot_z(yaw) @ np.asarray(centre, float)
    size = [2 * h for h in half]
    return (
        f'    <collision><origin xyz="{_fmt(xyz)}" rpy="0 0 {yaw:.10g}"/>'
        f'<geometry><box size="{_fmt(size)}"/></geometry></collision>'
    )


def _link_xml(name: str, mass: float, shapes: list[str]) -> str:
    i = mass * 0.05**2 / 2
    inertial = (
        f'    <inertial><mass value="{mass}"/><inertia ixx="{i:.6g}" ixy="0" ixz="0" '
        f'iyy="{i:.6g}" iyz="0" izz="{i:.6g}"/></inertial>'
    )
    return "\n".join([f'  <link name="{name}">', inertial, *shapes, "  </link>"])


def urdf_text(model: str = "panda") -> str:
    """The arm ``model`` (``LIMITS``: panda or fr3) with the hand and open fingers, as a URDF
    with franka_description's Panda names; the models differ in their joint limits only."""
    limits = LIMITS[model]
    lines = ['<?xml version="1.0"?>', f'<robot name="{model}">']
    caps = {k: [_capsule_xml(*c) for c in v] for k, v in CAPSULES.items()}
    lines.append(_link_xml("panda_link0", MASSES[0], caps["panda_link0"]))
    parent = "panda_link0"
    for i, (a, d, alpha) in enumerate(DH):
        xyz, roll = joint_origin(a, d, alpha)
        link = LINK_NAMES[i]
        lines.append(
            f'  <joint name="{JOINT_NAMES[i]}" type="revolute"><parent link="{parent}"/>'
            f'<child link="{link}"/><origin xyz="{_fmt(xyz)}" rpy="{roll:.17g} 0 0"/>'
            f'<axis xyz="0 0 1"/><limit lower="{limits.lower[i]}" upper="{limits.upper[i]}" '
            f'effort="{MAX_EFFORT[i]}" velocity="{limits.velocity[i]}"/></joint>'
        )
        lines.append(_link_xml(link, MASSES[i + 1], caps[link]))
        parent = link
    lines.append(
        '  <joint name="panda_joint8" type="fixed"><parent link="panda_link7"/>'
        f'<child link="panda_link8"/><origin xyz="0 0 {FLANGE_D}" rpy="0 0 0"/></joint>'
    )
    lines.append(_link_xml("panda_link8", MASSES[8], [_box_xml(*b) for b in HAND_BOXES]))
    lines.append(
        '  <joint name="panda_hand_joint" type="fixed"><parent link="panda_link8"/>'
        f'<child link="panda_hand"/><origin xyz="0 0 0" rpy="0 0 {HAND_YAW:.17g}"/></joint>'
    )
    lines.append(_link_xml("panda_hand", 0.001, []))
    lines.append("</robot>")
    return "\n".join(lines) + "\n"


def urdf_path(model: str = "panda") -> str:
    """``urdf_text(model)`` as a cached file PyBullet can load (``robots/urdf.py``), one per
    model."""
    return cached_urdf(model, urdf_text(model))
