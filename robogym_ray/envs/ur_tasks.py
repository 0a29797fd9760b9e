"""UR tasks without obstacles: the paper's end-effector positioning (Problem 2) and robo-gym's
EmptyEnvironmentUR (d.3) and EndEffectorPositioningUR (d.4; here
``EndEffectorPositioningRoboGymUR``).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, ClassVar

import numpy as np

from robogym_ray.envs.base import StepInfo
from robogym_ray.envs.frames import box, frame_xyz, in_frame, spherical
from robogym_ray.envs.outcomes import COLLISION, SUCCESS
from robogym_ray.envs.ur_common import JOINT_MAX, URTask, joint_obs_bounds, normalize_joints
from robogym_ray.errors import ConfigError
from robogym_ray.protocol import robot_server_pb2 as pb
from robogym_ray.protocol.client import RobotServerClient
from robogym_ray.robots.ur.geometry import URModel

PAPER_RADIUS_SCALE = 1.2 / 1.3
"""The paper's UR10 targets lie within 1.2 m; robo-gym's UR10 radius is 1.3 m (spec c.2.4)."""
START_SPREAD = (1.5, 0.25, 0.5, 1.0, 0.4, 3.14)
"""robo-gym's ``randomize_start`` half-widths (rad, env order) around the reset joints."""


def sample_target(rng: np.random.Generator, model: URModel, radius: float) -> np.ndarray:
    """A point uniform in the upper half ball of ``radius`` around base_link, minus singular
    regions.

    Rejected: ``x^2 + y^2 < min_r^2`` (near the base z axis: shoulder singularity, where the
    base joint's direction is undefined) and points farther than 95 % of ``reach`` from the
    shoulder (stretched-arm elbow singularity / out of reach).
    """
    shoulder = np.array([0.0, 0.0, model.d1])
    while True:
        p = rng.uniform(-radius, radius, 3)
        p[2] = abs(p[2])
        if np.linalg.norm(p) > radius or np.hypot(p[0], p[1]) < model.workspace_min_r:
            continue
        if np.linalg.norm(p - shoulder) <= 0.95 * model.reach:
            return p


class _TargetTask(URTask):
    """A fixed target (object 0, ``fixed_position``) sampled at reset."""

    rs_mode = "1object"
    velocity_scale = 0.1
    action_rate = 10.0
    max_episode_steps = 300
    reset_joints = (0.0, -2.5, 1.5, -1.5, -1.4, 0.0)
    randomize_default: ClassVar[bool] = False
    radius_scale: ClassVar[float] = 1.0
    success_distance: ClassVar[float] = 0.1

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self.target = np.zeros(3)
        self._prev_distance = 0.0

    def server_spec(self) -> tuple[str, str | None, dict[str, str]]:
        robot, scene, options = super().server_spec()
        options["object_0_model_name"] = "sphere50_no_collision"
        return robot, scene, options

    def _reset_server(self, client: RobotServerClient, options: Mapping[str, Any]) -> pb.State:
        if options.get("joint_positions") is not None:
            start = np.asarray(options["joint_positions"], dtype=np.float64)
        elif options.get("randomize_start", self.randomize_default):
            start = self.random_start(START_SPREAD)
        else:
            start = np.array(self.reset_joints)
        if options.get("ee_target_pose") is not None:
            self.target = np.asarray(options["ee_target_pose"], dtype=np.float64)[:3]
        else:
            self.target = sample_target(
                self.np_random, self.model, self.model.workspace_r * self.radius_scale
            )
        params = {f"object_0_{a}": float(v) for a, v in zip("xyz", self.target, strict=True)}
        msg = self.set_joints(client, start, {"object_0_function": "fixed_position"}, params)
        self._prev_distance = self.distance(msg)
        return msg

    def distance(self, msg: pb.State) -> float:
        return float(np.linalg.norm(self.target - frame_xyz(msg.state_dict, "ee")))


class EndEffectorPositioningUR(_TargetTask):
    """Problem 2 of the paper: bring the end effector (tool0) to a target point.

    ## Action space
    ``Box(-1, 1, (6,), float32)``: absolute joint position targets, normalised (times
    ``[2pi, 2pi, pi, 2pi, 2pi, 2pi]`` = rad, env order base ... wrist_3). The arm moves toward
    them at ``max_velocity_scale_factor`` 0.1 of its joint speed limits, 10 actions per second.

    ## Observation space
    ``Box((15,), float32)``

    | index | meaning | bounds |
    |---|---|---|
    | 0-2 | target in spherical coordinates ``[r, arccos(z/r), atan2(y, x)]`` | free |
    | 3-8 | joint positions, normalised by the limits | [-1.1, 1.1] |
    | 9-14 | joint velocities (rad/s) | free |

    ``target_frame="base"`` (default): the target's position in base_link (constant over an
    episode; the policy infers the end effector from the joints). ``target_frame="ee"``: the
    target in the end-effector frame, as robo-gym 0.x's UR10 env computed it.

    ## Reward
    ``50 * (previous distance - distance)`` per step (3D distance tool0 -> target, from the
    server's ``ee_to_ref_translation_*``); +100 when the distance <= 0.1 m; -200 on collision.

    ## Episode end
    terminated: ``success``, ``collision`` (self or ground contact; Sim only - the real arm
    reports none); truncated: ``max_steps_exceeded`` after 300 steps, ``server_restarted``.

    ## Reset
    Start: ``[0, -2.5, 1.5, -1.5, -1.4, 0]`` + U(+-[1.5, 0.25, 0.5, 1.0, 0.4, 3.14]) rad (random
    start configuration). Target: uniform in the upper half ball of radius ``1.2/1.3 * r`` around
    base_link (UR10: 1.2 m; r per model as in robo-gym: ur3 0.45, ur5 0.75, ur10 1.3, ur16e 0.8),
    minus singular regions (see ``sample_target``). Options: ``joint_positions``,
    ``ee_target_pose``, ``randomize_start``.

    ## Arguments
    ``ur_model`` (default ur10), ``target_frame`` ("base" | "ee"), ``fixed_joints`` (default
    none), and those of ``RobotServerEnv``.
    """

    default_fixed = ()
    randomize_default = True
    radius_scale = PAPER_RADIUS_SCALE
    progress_weight: ClassVar[float] = 50.0
    success_reward: ClassVar[float] = 100.0
    collision_reward: ClassVar[float] = -200.0

    def __init__(
        self, *, ur_model: str = "ur10", target_frame: str = "base", **kwargs: Any
    ) -> None:
        super().__init__(ur_model=ur_model, **kwargs)
        if target_frame not in ("base", "ee"):
            raise ConfigError(f"target_frame must be 'base' or 'ee', got {target_frame!r}")
        self.target_frame = target_frame
        low, high = joint_obs_bounds(6, 6)
        self.observation_space = box([-np.inf] * 3 + low, [np.inf] * 3 + high)

    def _to_obs(self, msg: pb.State) -> np.ndarray:
        sd = msg.state_dict
        target = self.target if self.target_frame == "base" else in_frame(sd, self.target, "ee")
        parts = [spherical(target), normalize_joints(self.joints(msg)), self.velocities(msg)]
        return np.concatenate(parts).astype(np.float32)

    def _evaluate(
        self, msg: pb.State, obs: np.ndarray, action: np.ndarray
    ) -> tuple[float, str | None, StepInfo]:
        distance = self.distance(msg)
        reward = self.progress_weight * (self._prev_distance - distance)
        self._prev_distance = distance
        info: StepInfo = {"distance": distance, "target_coord": self.target.copy()}
        if self.collided(msg):
            return reward + self.collision_reward, COLLISION, info
        if distance <= self.success_distance:
            return reward + self.success_reward, SUCCESS, info
        return reward, None, info


class EndEffectorPositioningRoboGymUR(_TargetTask):
    """robo-gym 2.0.1's ``EndEffectorPositioningURSim-v0`` (spec d.4): 27 observations, 5 actions.

    ## Action space
    ``Box(-1, 1, (5,), float32)`` by default (wrist_3 fixed at its reset position): normalised
    absolute joint targets; wrist_1 is restricted: ``(a + 1) / 2 * 3.79 - 3.48`` rad in
    [-3.48, 0.31]. So the action for joints ``q`` is not ``q`` over the limits: use
    ``action_for(q)`` (and ``joint_targets(action)`` for the other way).

    ## Observation space
    ``Box((27,), float32)``: target in the end-effector frame ``[r, theta, phi]`` (3, free),
    normalised joints (6, +-1.1), joint velocities (6, free), target xyz in base_link (3, free),
    tool0 xyz in base_link (3, free), previous full 6-joint action (6, +-1.01).

    ## Reward
    ``-0.005 * distance`` per step; +2 when the distance <= 0.1 m; -1 on collision.

    ## Episode end
    terminated: ``success``, ``collision`` (Sim only); truncated: ``max_steps_exceeded`` after 300
    steps (robo-gym: done), ``server_restarted``.

    ## Reset
    Joints ``[0, -2.5, 1.5, -1.5, -1.4, 0]`` (option ``randomize_start``); target uniform in the
    upper half ball of radius r (ur5 0.75, ur10 1.3, ...) without the singular regions.

    ## Arguments
    ``ur_model`` (default ur5), ``fixed_joints`` (default wrist_3), and ``RobotServerEnv``'s.
    """

    scene = "tabletop_no_collision"

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        low, high = joint_obs_bounds(6, 6)
        self.observation_space = box(
            [-np.inf] * 3 + low + [-np.inf] * 6 + [-1.01] * 6,
            [np.inf] * 3 + high + [np.inf] * 6 + [1.01] * 6,
        )
        self.previous_action = np.zeros(6)

    def _reset_server(self, client: RobotServerClient, options: Mapping[str, Any]) -> pb.State:
        self.previous_action = np.zeros(6)
        return super()._reset_server(client, options)

    def joint_targets(self, action: np.ndarray) -> np.ndarray:
        """As every UR task's, but wrist_1 on [-3.48, 0.31] rad (robo-gym's restrict_wrist_1)."""
        full = self.full_action(action, normalize_joints(self.start_joints))
        targets = full * JOINT_MAX
        targets[3] = (full[3] + 1.0) / 2.0 * (0.31 + 3.48) - 3.48
        return targets

    def _send(self, client: RobotServerClient, action: np.ndarray) -> pb.State:
        self.previous_action = self.full_action(action, normalize_joints(self.start_joints))
        return super()._send(client, action)

    def _to_obs(self, msg: pb.State) -> np.ndarray:
        sd = msg.state_dict
        parts = [
            spherical(in_frame(sd, self.target, "ee")),
            normalize_joints(self.joints(msg)),
            self.velocities(msg),
            self.target,
            frame_xyz(sd, "ee"),
            self.previous_action,
        ]
        return np.concatenate(parts).astype(np.float32)

    def _evaluate(
        self, msg: pb.State, obs: np.ndarray, action: np.ndarray
    ) -> tuple[float, str | None, StepInfo]:
        distance = self.distance(msg)
        info: StepInfo = {"distance": distance, "target_coord": self.target.copy()}
        reward = -0.005 * distance
        if self.collided(msg):
            return reward - 1.0, COLLISION, info
        if distance <= self.success_distance:
            return reward + 2.0, SUCCESS, info
        return reward, None, info


class EmptyEnvironmentUR(URTask):
    """robo-gym's ``EmptyEnvironmentURSim-v0`` (spec d.3): move freely, do not collide.

    ## Action space
    ``Box(-1, 1, (5,), float32)`` (wrist_3 fixed at its normalised reset position; see
    ``fixed_joints``): normalised absolute joint targets (times ``[2pi, 2pi, pi, 2pi, 2pi, 2pi]``).

    ## Observation space
    ``Box((12,), float32)``: normalised joint positions (6, +-1.1), joint velocities (6, free).

    ## Reward
    0 on every step.

    ## Episode end
    terminated: ``collision`` (Sim only); truncated after 300 steps with final_status
    ``success`` (surviving is the task; robo-gym reports done), ``server_restarted``.
    ``info["rs_state"]`` is the server's state_dict.

    ## Reset
    Joints ``[0, -2.5, 1.5, 0, -1.4, 0]`` (option ``joint_positions``).

    ## Arguments
    ``ur_model`` (default ur5), ``fixed_joints``, and ``RobotServerEnv``'s.
    """

    max_episode_steps = 300
    limit_status = SUCCESS

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self.observation_space = box(*joint_obs_bounds(6, 6))

    def _reset_server(self, client: RobotServerClient, options: Mapping[str, Any]) -> pb.State:
        joints = options.get("joint_positions")
        start = np.array(self.reset_joints if joints is None else joints, dtype=np.float64)
        return self.set_joints(client, start)

    def _to_obs(self, msg: pb.State) -> np.ndarray:
        return np.concatenate([normalize_joints(self.joints(msg)), self.velocities(msg)]).astype(
            np.float32
        )

    def _evaluate(
        self, msg: pb.State, obs: np.ndarray, action: np.ndarray
    ) -> tuple[float, str | None, StepInfo]:
        info: StepInfo = {"rs_state": dict(msg.state_dict)}
        return 0.0, (COLLISION if self.collided(msg) else None), info
