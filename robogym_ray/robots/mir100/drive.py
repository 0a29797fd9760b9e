"""Kinematic differential-drive model of the MiR100 base (pure math, no PyBullet).

The ROS reference drives the MiR100 with ``diff_drive_controller``: the commanded twist is clipped
to velocity limits and its change per control period to acceleration limits, and the wheels then
follow it. We reproduce exactly that part (set-point -> limited twist -> unicycle pose) and skip
wheel/ground dynamics, which is what makes one 0.1 s action cost microseconds instead of a
dynamic-physics rollout.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

TWO_PI = 2.0 * math.pi


@dataclass(frozen=True)
class DriveLimits:
    """Velocity and acceleration limits of the diff-drive controller (mir_robot defaults)."""

    max_linear_velocity: float = 1.0
    """|v| limit in m/s."""
    max_angular_velocity: float = 1.5
    """|omega| limit in rad/s."""
    max_linear_acceleration: float = 2.0
    """|dv/dt| limit in m/s^2."""
    max_angular_acceleration: float = 2.5
    """|domega/dt| limit in rad/s^2."""


@dataclass
class BaseState:
    """Pose of the drive-axle centre in the world (m, m, rad) and the robot-frame twist."""

    x: float = 0.0
    y: float = 0.0
    yaw: float = 0.0
    v: float = 0.0
    w: float = 0.0

    def copy(self) -> BaseState:
        return BaseState(self.x, self.y, self.yaw, self.v, self.w)


def wrap_angle(angle: float) -> float:
    """Wrap to (-pi, pi], the range the ROS server reports yaw in (pi stays pi, -pi becomes pi)."""
    return angle - TWO_PI * math.ceil((angle - math.pi) / TWO_PI)


def clip(value: float, limit: float) -> float:
    return max(-limit, min(limit, value))


def approach(current: float, target: float, max_step: float) -> float:
    """Move ``current`` towards ``target`` by at most ``max_step`` (acceleration limiting)."""
    return current + clip(target - current, max_step)


def integrate(
    state: BaseState, v_set: float, w_set: float, dt: float, limits: DriveLimits
) -> BaseState:
    """One substep: accel-limit the twist towards the (already clipped) set-point, move the pose.

    The pose moves with the mean of the old and new twist (exact for a linear velocity ramp) along
    a circular arc (exact for constant twist), so the result hardly depends on the substep.
    """
    v = approach(state.v, v_set, limits.max_linear_acceleration * dt)
    w = approach(state.w, w_set, limits.max_angular_acceleration * dt)
    v_mid = 0.5 * (state.v + v)
    w_mid = 0.5 * (state.w + w)
    dtheta = w_mid * dt
    if abs(dtheta) < 1e-9:
        # Straight line; the arc formula would divide by ~0. Use the mid heading (2nd order).
        heading = state.yaw + 0.5 * dtheta
        x = state.x + v_mid * dt * math.cos(heading)
        y = state.y + v_mid * dt * math.sin(heading)
    else:
        radius = v_mid / w_mid
        x = state.x + radius * (math.sin(state.yaw + dtheta) - math.sin(state.yaw))
        y = state.y - radius * (math.cos(state.yaw + dtheta) - math.cos(state.yaw))
    return BaseState(x, y, wrap_angle(state.yaw + dtheta), v, w)
