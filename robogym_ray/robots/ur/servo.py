"""A PD servo that tracks streamed joint-position targets: the UR's ``servo_pos`` action mode.

Isaac Lab's deploy tasks drive the UR10e with implicit PD actuators (``isaaclab_assets``
``UR10e_CFG``: stiffness / damping 1320 / 72.66 for the shoulder joints, 600 / 34.64 for the
elbow, 216 / 29.39 for the wrists; gravity off), and Isaac ROS deploys them by streaming one
joint target per policy step to the UR driver's impedance controller. Neither smears a target
over a trajectory the way robo-gym's ROS bridge does (``controller.py``), so this mode holds
each target until the next and tracks it every physics step.

The model is one decoupled joint of unit inertia per axis, integrated implicitly (backward
Euler, as PhysX integrates an implicit drive) at Isaac Lab's physics step, 1/120 s. Isaac Lab's
arm is a USD whose link inertias were not read; the gains are critically damped for a unit
inertia (damping = 2 sqrt(stiffness) for the shoulder and the wrists), which is what they were
evidently tuned for. In steady motion the PD force balances, so a joint held ``e`` rad behind
its target moves at ``stiffness / damping * e`` rad/s whatever the inertia: that speed, the one
the deploy task's action scale buys, is reproduced exactly. No gravity acts (the task turns it
off). On top of the PD the UR's limits hold: joint speed (``max_velocity``), joint acceleration
(``MAX_ACCELERATION``) and the position limits.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np

from robogym_ray.errors import InvalidStateError
from robogym_ray.robots.validation import check_range

PHYSICS_DT = 1.0 / 120.0
"""Isaac Lab's physics step for the deploy reach (``sim.dt``; the policy acts every second)."""
STIFFNESS = np.array([1320.0, 1320.0, 600.0, 216.0, 216.0, 216.0])
"""Isaac Lab's UR10e gains (env order: shoulder_pan, shoulder_lift, elbow, wrist_1..3)."""
DAMPING = np.array([72.6636085, 72.6636085, 34.64101615, 29.39387691, 29.39387691, 29.39387691])
MAX_ACCELERATION = 5.0
"""rad/s^2, every joint. Universal Robots publish no joint acceleration limit (the arm is bound
by its torques, as their ROS 2 driver's ``ur_moveit_config/config/joint_limits.yaml`` notes);
that file's 5 rad/s^2 is the bound their own planning uses, and the one taken here."""
REST_VELOCITY = 1e-9
"""rad/s: slower than this a joint is at rest."""
PARAMS = {"stiffness_scale": (1.0, 0.01, 10.0), "damping_scale": (1.0, 0.01, 10.0),
          "friction": (0.0, 0.0, 10.0)}  # fmt: skip
"""SetState float params ``servo_<name>_<j>`` (j: joint, env order): nominal, low, high."""


def nominal_params() -> dict[str, np.ndarray]:
    """Isaac Lab's nominal actuator: gains unscaled, no friction."""
    return {name: np.full(6, nominal) for name, (nominal, _, _) in PARAMS.items()}


def servo_params(float_params: Mapping[str, float]) -> dict[str, np.ndarray] | None:
    """The servo's per-joint parameters a SetState asks for (nominal where a key is absent), or
    None when it names none.

    Raises:
        InvalidStateError: a ``servo_*`` key that is not one of them, or a value out of range.
    """
    keys = [k for k in float_params if k.startswith("servo_")]
    if not keys:
        return None
    known = {f"servo_{name}_{j}" for name in PARAMS for j in range(6)}
    unknown = sorted(set(keys) - known)
    if unknown:
        raise InvalidStateError(
            f"unknown SetState float params {unknown[:3]}; the servo's are servo_<name>_<joint> "
            f"with name one of {sorted(PARAMS)} and joint 0-5 (env order)"
        )
    out = {}
    for name, (nominal, low, high) in PARAMS.items():
        values = [float_params.get(f"servo_{name}_{j}", nominal) for j in range(6)]
        out[name] = np.array([check_range(f"servo_{name}_{j}", v, low, high)
                              for j, v in enumerate(values)])  # fmt: skip
    return out


class JointServo:
    """Per-joint PD tracking of a held target, within the UR's speed, acceleration and position
    limits; the same controller interface as ``JointTrajectoryController``.

    Args:
        max_velocity: vmax_j (rad/s) = scale factor x Vabs_j.
        limits: |q_j| limits (rad); targets are clipped into them.
        max_acceleration: rad/s^2, every joint.
    """

    def __init__(
        self,
        max_velocity: np.ndarray,
        limits: np.ndarray,
        max_acceleration: float = MAX_ACCELERATION,
    ) -> None:
        self.max_velocity = np.asarray(max_velocity, dtype=np.float64)
        self.limits = np.asarray(limits, dtype=np.float64)
        self.max_acceleration = float(max_acceleration)
        self.position = np.zeros(6)
        self.velocity = np.zeros(6)
        self.target = np.zeros(6)
        self.stiffness = STIFFNESS.copy()
        self.damping = DAMPING.copy()
        self.friction = np.zeros(6)
        """Coulomb friction (rad/s^2 on the unit inertia), opposing motion."""

    def reset(self, position: np.ndarray) -> None:
        """Place the arm at ``position`` (clipped to limits), at rest, holding it."""
        self.position = self.clip(np.asarray(position, dtype=np.float64))
        self.velocity = np.zeros(6)
        self.target = self.position.copy()

    def set_gains(
        self, stiffness_scale: np.ndarray, damping_scale: np.ndarray, friction: np.ndarray
    ) -> None:
        """Isaac Lab's actuator randomisation: gains scaled, friction added (per joint)."""
        self.stiffness = STIFFNESS * np.asarray(stiffness_scale, dtype=np.float64)
        self.damping = DAMPING * np.asarray(damping_scale, dtype=np.float64)
        self.friction = np.asarray(friction, dtype=np.float64).copy()

    def clip(self, target: np.ndarray) -> np.ndarray:
        """``target`` clipped into the joint limits."""
        return np.minimum(np.maximum(target, -self.limits), self.limits)

    def command(self, target: np.ndarray, clipped: bool = False) -> None:
        """Hold ``target`` (clipped to the limits) until the next command."""
        self.target = np.asarray(target, dtype=np.float64) if clipped else self.clip(target)

    def stop(self) -> None:
        """No command: hold where the arm is now (the servo brakes it to rest there)."""
        self.target = self.position.copy()

    def step(self, dt: float) -> bool:
        """Advance ``dt`` seconds in physics steps of at most ``PHYSICS_DT``; returns whether
        the arm moved."""
        n = max(1, math.ceil(dt / PHYSICS_DT - 1e-9))
        moved = False
        for _ in range(n):
            moved = self._substep(dt / n) or moved
        return moved

    def _substep(self, h: float) -> bool:
        q, v = self.position, self.velocity
        if not v.any() and np.array_equal(q, self.target):
            return False  # at rest on target: nothing acts (friction cannot start motion)
        kp, kd = self.stiffness, self.damping
        # Backward Euler of v' = kp (target - q) - kd v: stable for any gain at this step.
        free = (v + h * kp * (self.target - q)) / (1.0 + h * kd + h * h * kp)
        free = np.sign(free) * np.maximum(np.abs(free) - h * self.friction, 0.0)
        dv = h * self.max_acceleration
        v_new = np.clip(np.clip(free, v - dv, v + dv), -self.max_velocity, self.max_velocity)
        # The implicit PD only decays a velocity; below this it has stopped (and the arm's
        # contact checks, run after every step that moved it, can rest).
        v_new[np.abs(v_new) < REST_VELOCITY] = 0.0
        q_new = q + h * v_new
        held = self.clip(q_new)
        v_new[held != q_new] = 0.0  # a joint stopped at its limit stands still
        self.position, self.velocity = held, v_new
        return bool(np.any(held != q))
