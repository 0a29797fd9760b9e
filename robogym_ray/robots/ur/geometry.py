"""Universal Robots arm models: parameters, pure-numpy forward kinematics, and URDF generation.

Everything is derived from the DH table of spec e.2 (``default_kinematics.yaml`` of
``ur_description``). The kinematic chain mirrors that package's URDF: ``base_link`` ->
``base_link_inertia`` (rotated pi about z, so at all-zero joints the arm extends along +x of
``base_link``) -> six revolute joints -> ``flange`` -> ``tool0``. Collision geometry is a few
cylinders per link, sized so that the usual poses are collision free while folding the elbow,
hitting the base or swinging the tool into the forearm do collide.

Joint arrays in this module are in *env order* ``[shoulder_pan, shoulder_lift, elbow, wrist_1,
wrist_2, wrist_3]`` (the URDF chain order); the wire uses ROS order (see ``ROS_FROM_ENV``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from robogym_ray.robots.urdf import cached_urdf

JOINT_NAMES: tuple[str, ...] = (
    "shoulder_pan_joint",
    "shoulder_lift_joint",
    "elbow_joint",
    "wrist_1_joint",
    "wrist_2_joint",
    "wrist_3_joint",
)
"""URDF joint names in env order."""
LINK_NAMES: tuple[str, ...] = (
    "shoulder_link",
    "upper_arm_link",
    "forearm_link",
    "wrist_1_link",
    "wrist_2_link",
    "wrist_3_link",
)
"""The six moving links (child of each joint), which carry the contact sensors in Gazebo."""
ROS_FROM_ENV: tuple[int, ...] = (2, 1, 0, 3, 4, 5)
"""``ros = env[ROS_FROM_ENV]`` and, the permutation being its own inverse, ``env = ros[...]``."""

TWO_PI = 6.28318530718
POSITION_LIMITS = np.array([TWO_PI, TWO_PI, math.pi, TWO_PI, TWO_PI, TWO_PI])
"""|q| limits in env order (rad): ±2pi everywhere except the elbow (±pi); same for all models."""
BASE_LINK_HEIGHT = 0.1
"""Default height of base_link above the world origin (m): ur_robot_server.launch's ``z``
default, on the tabletop's top. The ``z`` launch argument moves it (IsaacReach: 0.0, on the
demo table)."""
BASE_HEIGHT_OPTION = "z"
"""The launch argument that sets the base height (the base_link pose's z in the world)."""


@dataclass(frozen=True)
class URModel:
    """Geometry and limits of one UR model."""

    name: str
    d1: float
    a2: float
    a3: float
    d4: float
    d5: float
    d6: float
    max_velocity: tuple[float, ...]
    """Vabs per joint (rad/s), env order."""
    workspace_r: float
    """Radius of the ball targets are drawn from (EndEffectorPositioning env)."""
    workspace_min_r: float
    """Targets closer than this to the base z axis are redrawn."""
    link_radius: float
    """Radius of the base, shoulder and upper-arm cylinders (m)."""
    forearm_radius: float
    wrist_radius: float
    masses: tuple[float, ...]
    """Masses (kg) of base_link_inertia and the six moving links."""

    @property
    def reach(self) -> float:
        """``|a2| + |a3| + d5`` (m): the stretched-arm distance from the shoulder to the wrist."""
        return abs(self.a2) + abs(self.a3) + self.d5

    @property
    def dh(self) -> tuple[float, float, float, float, float, float]:
        return (self.d1, self.a2, self.a3, self.d4, self.d5, self.d6)

    @property
    def position_limits(self) -> np.ndarray:
        return POSITION_LIMITS.copy()


_V3 = (3.14159, 3.14159, 3.14159, 6.28319, 6.28319, 6.28319)
_V5 = (3.14159,) * 6
_V10 = (2.0943951, 2.0943951, 3.14159, 3.14159, 3.14159, 3.14159)
_M3 = (2.0, 2.0, 3.42, 1.26, 0.8, 0.8, 0.35)
_M5 = (4.0, 3.7, 8.393, 2.275, 1.219, 1.219, 0.1879)
_M10 = (4.0, 7.778, 12.93, 3.87, 1.96, 1.96, 0.202)
_M16 = (4.0, 7.369, 10.45, 4.321, 2.18, 2.033, 0.907)

UR_MODELS: dict[str, URModel] = {
    m.name: m
    for m in (
        URModel("ur3", 0.1519, -0.24365, -0.21325, 0.11235, 0.08535, 0.0819,
                _V3, 0.45, 0.2, 0.045, 0.038, 0.032, _M3),
        URModel("ur3e", 0.152, -0.244, -0.213, 0.131, 0.085, 0.092,
                _V3, 0.45, 0.2, 0.045, 0.038, 0.032, _M3),
        URModel("ur5", 0.089159, -0.425, -0.39225, 0.10915, 0.09465, 0.0823,
                _V5, 0.75, 0.2, 0.06, 0.04, 0.04, _M5),
        URModel("ur5e", 0.163, -0.425, -0.39225, 0.134, 0.100, 0.100,
                _V5, 0.75, 0.2, 0.06, 0.045, 0.042, _M5),
        URModel("ur10", 0.1273, -0.612, -0.5723, 0.163941, 0.1157, 0.0922,
                _V10, 1.3, 0.3, 0.075, 0.055, 0.05, _M10),
        URModel("ur10e", 0.1807, -0.6127, -0.57155, 0.17415, 0.11985, 0.11655,
                _V10, 1.3, 0.3, 0.075, 0.055, 0.05, _M10),
        URModel("ur16e", 0.1807, -0.4784, -0.36, 0.17415, 0.11985, 0.11655,
                _V10, 0.8, 0.3, 0.075, 0.055, 0.05, _M16),
    )
}  # fmt: skip
"""All seven models by name (DH of spec e.2, limits, Vabs, workspace radii, sizes). The UR10e's
DH is Universal Robots' published one (as in ur_description's ``default_kinematics.yaml`` and
Isaac Lab's UR10e, which IsaacDeployReachUR10e uses); robo-gym's fork rounds it to the
millimetre (spec e.2: 0.181, -0.613, -0.571, 0.174, 0.120, 0.117), at most 0.7 mm from these."""


# -- kinematics -------------------------------------------------------------------------------
def _rpy(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """URDF fixed-axis rotation Rz(yaw) @ Ry(pitch) @ Rx(roll)."""
    cr, sr, cp, sp, cy, sy = (
        math.cos(roll), math.sin(roll), math.cos(pitch), math.sin(pitch), math.cos(yaw),
        math.sin(yaw),
    )  # fmt: skip
    return np.array(
        [
            [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
            [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
            [-sp, cp * sr, cp * cr],
        ]
    )


def _transform(xyz: tuple[float, float, float], rpy: tuple[float, float, float]) -> np.ndarray:
    m = np.eye(4)
    m[:3, :3] = _rpy(*rpy)
    m[:3, 3] = xyz
    return m


def joint_origins(model: URModel) -> list[tuple[tuple[float, ...], tuple[float, ...]]]:
    """(xyz, rpy) of the six revolute joints in their parent link (spec e.2 "Joint origins")."""
    d1, a2, a3, d4, d5, d6 = model.dh
    half_pi = math.pi / 2
    return [
        ((0.0, 0.0, d1), (0.0, 0.0, 0.0)),
        ((0.0, 0.0, 0.0), (half_pi, 0.0, 0.0)),
        ((a2, 0.0, 0.0), (0.0, 0.0, 0.0)),
        ((a3, 0.0, d4), (0.0, 0.0, 0.0)),
        ((0.0, -d5, 0.0), (half_pi, 0.0, 0.0)),
        ((0.0, d6, 0.0), (half_pi, math.pi, math.pi)),
    ]


BASE_INERTIA_RPY = (0.0, 0.0, math.pi)
FLANGE_RPY = (0.0, -math.pi / 2, -math.pi / 2)
"""wrist_3_link -> flange."""
TOOL0_RPY = (math.pi / 2, 0.0, math.pi / 2)
"""flange -> tool0."""
TOOL1_RPY = (0.0, -1.5707, 3.1415)
"""tool0 -> tool1, IsaacLab's end-effector frame: ur_robot_server.launch (robot servers 2.1.0)
publishes it as a static transform ``0 0 0 3.1415 -1.5707 0 tool0 tool1`` (x y z yaw pitch
roll). The truncated angles are kept: they are what the ROS server reports."""
EE_FRAMES: tuple[str, ...] = ("tool0", "tool1", "wrist_3_link")
"""Frames the ``ee_frame`` launch argument may name, the launch file's default first;
``wrist_3_link`` is Isaac Lab's deploy-reach end effector (a link of the tf tree, so the ROS
server can report it too)."""


def _quat_xyzw(r: np.ndarray) -> np.ndarray:
    """Unit quaternion (x, y, z, w) of a rotation matrix (Shepperd's method)."""
    t = r[0, 0] + r[1, 1] + r[2, 2]
    if t > 0:
        s = 2.0 * math.sqrt(t + 1.0)
        q = [(r[2, 1] - r[1, 2]) / s, (r[0, 2] - r[2, 0]) / s, (r[1, 0] - r[0, 1]) / s, s / 4]
    elif r[0, 0] > r[1, 1] and r[0, 0] > r[2, 2]:
        s = 2.0 * math.sqrt(1.0 + r[0, 0] - r[1, 1] - r[2, 2])
        q = [s / 4, (r[0, 1] + r[1, 0]) / s, (r[0, 2] + r[2, 0]) / s, (r[2, 1] - r[1, 2]) / s]
    elif r[1, 1] > r[2, 2]:
        s = 2.0 * math.sqrt(1.0 + r[1, 1] - r[0, 0] - r[2, 2])
        q = [(r[0, 1] + r[1, 0]) / s, s / 4, (r[1, 2] + r[2, 1]) / s, (r[0, 2] - r[2, 0]) / s]
    else:
        s = 2.0 * math.sqrt(1.0 + r[2, 2] - r[0, 0] - r[1, 1])
        q = [(r[0, 2] + r[2, 0]) / s, (r[1, 2] + r[2, 1]) / s, s / 4, (r[1, 0] - r[0, 1]) / s]
    quat = np.asarray(q)
    return quat / np.linalg.norm(quat)


def forward_kinematics(
    model: str | URModel, q_env_order: np.ndarray | list[float]
) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Poses of every link frame in ``base_link``, computed with numpy only.

    Args:
        model: a name from ``UR_MODELS`` or a ``URModel``.
        q_env_order: joint positions (rad), env order.

    Returns:
        ``{frame: (xyz, quat_xyzw)}`` for ``base_link_inertia``, the six links of
        ``LINK_NAMES``, ``flange``, ``tool0`` and ``tool1``.
    """
    spec = UR_MODELS[model] if isinstance(model, str) else model
    q = np.asarray(q_env_order, dtype=np.float64).reshape(6)
    m = _transform((0.0, 0.0, 0.0), BASE_INERTIA_RPY)
    frames = {"base_link_inertia": m}
    for name, (xyz, rpy), angle in zip(LINK_NAMES, joint_origins(spec), q, strict=True):
        m = m @ _transform(xyz, rpy) @ _transform((0.0, 0.0, 0.0), (0.0, 0.0, float(angle)))
        frames[name] = m
    frames["flange"] = m = m @ _transform((0.0, 0.0, 0.0), FLANGE_RPY)
    frames["tool0"] = m = m @ _transform((0.0, 0.0, 0.0), TOOL0_RPY)
    frames["tool1"] = m @ _transform((0.0, 0.0, 0.0), TOOL1_RPY)
    return {k: (v[:3, 3].copy(), _quat_xyzw(v[:3, :3])) for k, v in frames.items()}


# -- URDF -------------------------------------------------------------------------------------
Cylinder = tuple[float, float, tuple[float, float, float], tuple[float, float, float]]
"""(radius, length, centre xyz, rpy) of one collision cylinder in its link frame."""
_ALONG_X = (0.0, math.pi / 2, 0.0)
_ALONG_Y = (math.pi / 2, 0.0, 0.0)
_ALONG_Z = (0.0, 0.0, 0.0)
_FRAME_MASS = 0.001


def collision_cylinders(model: URModel) -> dict[str, list[Cylinder]]:
    """Collision cylinders per link.

    The upper arm runs beside the shoulder at ``1.25 d4`` along the lift axis and the forearm at
    ``0.15 d4`` (the UR5's 0.136 / 0.016 m), which keeps the upper arm clear of the base and the
    forearm clear of the wrist housings in every pose; only genuinely folded poses collide.
    """
    _, a2, a3, d4, d5, d6 = model.dh
    ru, rf, rw = model.link_radius, model.forearm_radius, model.wrist_radius
    so, fo = 1.25 * d4, 0.15 * d4
    base_h = 0.6 * model.d1
    return {
        "base_link_inertia": [(ru, base_h, (0.0, 0.0, base_h / 2), _ALONG_Z)],
        "shoulder_link": [
            (ru, 2 * ru, (0.0, 0.0, 0.0), _ALONG_Z),
            (ru, so, (0.0, -so / 2, 0.0), _ALONG_Y),  # lift-axis housing, towards the upper arm
        ],
        "upper_arm_link": [
            (ru, abs(a2), (a2 / 2, 0.0, so), _ALONG_X),
            (rf, so - fo, (a2, 0.0, (so + fo) / 2), _ALONG_Z),  # elbow housing
        ],
        "forearm_link": [(rf, abs(a3), (a3 / 2, 0.0, fo), _ALONG_X)],
        "wrist_1_link": [(rw, d4 - fo + rw, (0.0, 0.0, (rw - d4 + fo) / 2), _ALONG_Z)],
        "wrist_2_link": [(rw, d5 + rw, (0.0, 0.0, (rw - d5) / 2), _ALONG_Z)],
        "wrist_3_link": [(0.85 * rw, d6 - rw, (0.0, 0.0, -(d6 - rw) / 2), _ALONG_Z)],
    }


def _fmt(values: tuple[float, ...]) -> str:
    return " ".join(f"{v:.10g}" for v in values)


def _link_xml(name: str, mass: float, cylinders: list[Cylinder]) -> str:
    parts = [f'  <link name="{name}">']
    # A solid-cylinder-ish inertia: only plausibility matters, the controller is kinematic. Frame
    # links get a token mass so the URDF importer does not warn about missing inertials.
    r = cylinders[0][0] if cylinders else 0.01
    i = mass * r * r / 2
    parts.append(
        f'    <inertial><mass value="{mass}"/>'
        f'<inertia ixx="{i:.6g}" ixy="0" ixz="0" iyy="{i:.6g}" iyz="0" izz="{i:.6g}"/>'
        "</inertial>"
    )
    for radius, length, xyz, rpy in cylinders:
        parts.append(
            f'    <collision><origin xyz="{_fmt(xyz)}" rpy="{_fmt(rpy)}"/>'
            f'<geometry><cylinder radius="{radius:.6g}" length="{length:.6g}"/></geometry>'
            "</collision>"
        )
    parts.append("  </link>")
    return "\n".join(parts)


def _joint_xml(name: str, kind: str, parent: str, child: str, xyz, rpy, limit: str = "") -> str:
    axis = '<axis xyz="0 0 1"/>' if kind == "revolute" else ""
    return (
        f'  <joint name="{name}" type="{kind}"><parent link="{parent}"/><child link="{child}"/>'
        f'<origin xyz="{_fmt(xyz)}" rpy="{_fmt(rpy)}"/>{axis}{limit}</joint>'
    )


def urdf_text(model: str | URModel) -> str:
    """The URDF of one model (same link/joint names and frames as ``ur_description``)."""
    spec = UR_MODELS[model] if isinstance(model, str) else model
    cyl = collision_cylinders(spec)
    zero = (0.0, 0.0, 0.0)
    lines = ['<?xml version="1.0"?>', f'<robot name="{spec.name}">']
    lines.append(_link_xml("base_link", _FRAME_MASS, []))
    lines.append(_joint_xml("base_link-base_link_inertia", "fixed", "base_link",
                            "base_link_inertia", zero, BASE_INERTIA_RPY))  # fmt: skip
    lines.append(_link_xml("base_link_inertia", spec.masses[0], cyl["base_link_inertia"]))
    parent = "base_link_inertia"
    for i, (joint, link, (xyz, rpy)) in enumerate(
        zip(JOINT_NAMES, LINK_NAMES, joint_origins(spec), strict=True)
    ):
        lim = float(POSITION_LIMITS[i])
        limit = (
            f'<limit lower="{-lim:.17g}" upper="{lim:.17g}" effort="150" '
            f'velocity="{spec.max_velocity[i]:.8g}"/>'
        )
        lines.append(_joint_xml(joint, "revolute", parent, link, xyz, rpy, limit))
        lines.append(_link_xml(link, spec.masses[i + 1], cyl[link]))
        parent = link
    lines.append(_joint_xml("wrist_3-flange", "fixed", "wrist_3_link", "flange", zero, FLANGE_RPY))
    lines.append(_link_xml("flange", _FRAME_MASS, []))
    lines.append(_joint_xml("flange-tool0", "fixed", "flange", "tool0", zero, TOOL0_RPY))
    lines.append(_link_xml("tool0", _FRAME_MASS, []))
    lines.append(_joint_xml("tool0-tool1", "fixed", "tool0", "tool1", zero, TOOL1_RPY))
    lines.append(_link_xml("tool1", _FRAME_MASS, []))
    lines.append("</robot>")
    return "\n".join(lines) + "\n"


def urdf_path(model: str | URModel) -> str:
    """The model's URDF as a cached file PyBullet can load (``robots/urdf.py``).

    Generated rather than shipped so the geometry can never drift from ``UR_MODELS``.
    """
    name = UR_MODELS[model].name if isinstance(model, str) else model.name
    return cached_urdf(name, urdf_text(model))
