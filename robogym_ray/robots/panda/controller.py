"""A kinematic joint position controller for the Panda.

robo-gym's Panda bridge (abs_pos, ``pos_action_impl`` set_pos) hands each action to
franka_ros_interface's ``set_joint_positions`` and sleeps one action cycle; the arm then follows
its position controller. We reproduce that envelope kinematically: every tick moves all joints
along the straight line to the target, synchronised so they arrive together, no joint faster
than its speed limit (``max_velocity_scale_factor`` x the published limit), and stops there.
Targets are clipped into the joint limits, so positions never leave them.
"""

from __future__ import annotations

import numpy as np


class JointPositionController:
    """Straight joint-space segments at the speed limit, re-planned on every command."""

    def __init__(self, max_velocity: np.ndarray, lower: np.ndarray, upper: np.ndarray) -> None:
        self.max_velocity = np.asarray(max_velocity, dtype=np.float64)
        self.lower = np.asarray(lower, dtype=np.float64)
        self.upper = np.asarray(upper, dtype=np.float64)
        n = self.max_velocity.size
        self.position = np.zeros(n)
        self.velocity = np.zeros(n)
        self.target = np.zeros(n)

    def clip(self, q: np.ndarray) -> np.ndarray:
        return np.minimum(np.maximum(q, self.lower), self.upper)

    def reset(self, position: np.ndarray) -> None:
        """Place the arm at ``position`` (clipped), at rest, holding it."""
        self.position = self.clip(np.asarray(position, dtype=np.float64))
        self.target = self.position.copy()
        self.velocity = np.zeros_like(self.position)

    def command(self, target: np.ndarray) -> None:
        """Head for ``target`` (clipped to the limits) from wherever the arm is."""
        self.target = self.clip(np.asarray(target, dtype=np.float64))

    def step(self, dt: float) -> bool:
        """Advance ``dt`` seconds; returns whether the arm moved."""
        delta = self.target - self.position
        if not np.any(delta):
            self.velocity = np.zeros_like(self.position)
            return False
        duration = float((np.abs(delta) / self.max_velocity).max())
        if duration <= dt:
            self.position = self.target.copy()
            self.velocity = delta / dt
        else:
            self.velocity = delta / duration
            self.position = self.position + self.velocity * dt
        return True
