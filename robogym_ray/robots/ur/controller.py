"""A kinematic stand-in for the UR's joint-trajectory controller (spec c.2.5, e.2).

The ROS bridge turns every command into a one-point trajectory from the current position to the
target, lasting ``max_j max(|delta_j| / vmax_j, 0.5 s)``; the controller interpolates it (positions
only, hence linearly) and an empty trajectory preempts it, stopping the arm. We reproduce that
envelope kinematically instead of simulating the effort PID of Gazebo: every actuation tick that
carries a command re-plans the segment from where the arm is, ``step(dt)`` moves along it, and
``stop()`` preempts it. Re-planning each tick gives each joint ``delta * dt / duration`` per tick,
all joints synchronised and never faster than vmax, which is the per-step motion of spec c.2.5.
Being kinematic is what makes thousands of actions per second possible.
"""

from __future__ import annotations

import numpy as np

MIN_DURATION = 0.5
"""Shortest trajectory the ROS bridge sends (s); it also makes small corrections slow down."""


class JointTrajectoryController:
    """Linear one-point trajectories with preemption, joint positions clipped to limits."""

    def __init__(self, max_velocity: np.ndarray, limits: np.ndarray) -> None:
        """
        Args:
            max_velocity: vmax_j (rad/s) = scale factor x Vabs_j.
            limits: |q_j| limits (rad); targets are clipped into them, so positions never leave.
        """
        self.max_velocity = np.asarray(max_velocity, dtype=np.float64)
        self.limits = np.asarray(limits, dtype=np.float64)
        self.position = np.zeros(6)
        self.velocity = np.zeros(6)
        self._start = np.zeros(6)
        self._delta = np.zeros(6)
        self._duration = MIN_DURATION
        self._elapsed = 0.0
        self.active = False
        """Whether a trajectory is being followed (False after it ends or is preempted)."""

    def reset(self, position: np.ndarray) -> None:
        """Place the arm at ``position`` (clipped to limits), at rest, with no trajectory."""
        self.position = self.clip(np.asarray(position, dtype=np.float64))
        self.stop()

    def clip(self, target: np.ndarray) -> np.ndarray:
        """``target`` clipped into the joint limits."""
        return np.minimum(np.maximum(target, -self.limits), self.limits)

    def command(self, target: np.ndarray, clipped: bool = False) -> None:
        """(Re)plan a segment from the current position to ``target`` (clipped to the limits).

        Args:
            clipped: the caller already clipped ``target`` (saves work on every tick).
        """
        if not clipped:
            target = self.clip(target)
        self._start = self.position
        self._delta = target - self._start
        self._duration = max(float((np.abs(self._delta) / self.max_velocity).max()), MIN_DURATION)
        self._elapsed = 0.0
        self.active = True

    def stop(self) -> None:
        """Preempt: hold the current position, velocity 0."""
        self.active = False
        self.velocity = np.zeros(6)

    def step(self, dt: float) -> bool:
        """Advance ``dt`` seconds along the trajectory; returns whether the arm moved."""
        if not self.active:
            return False
        self._elapsed += dt
        fraction = min(self._elapsed / self._duration, 1.0)
        self.position = self._start + self._delta * fraction
        if fraction >= 1.0:
            self.active = False
            self.velocity = np.zeros(6)
        else:
            self.velocity = self._delta / self._duration
        return True
