"""robo-gym 2.1.0's modular manipulator tasks, robot-agnostic (``robo_gym/envs/manipulator/``).

2.1.0 builds an env from nodes (one action node, observation nodes, one reward node) configured
by keyword arguments. Here the same semantics are two classes placed in front of an arm's task
class (``URTask``, ``PandaTask``), which brings the wire (joint order, SetState, key checks):

* ``ModularArmTask`` - 2.1.0's ``ManipulatorBaseEnv``: normalised absolute joint targets, some
  joints fixed (``fix_<joint>``), reward 0, a collision ends the episode, surviving the step
  limit is a success;
* ``PoseTask`` - 2.1.0's ``ManipulatorEePosEnv``: bring the end effector to a target pose
  (position, and the rotation when ``ee_rotation_matters``), with its target sampling, reward and
  "continue from the last pose" resets.

A robot binding (``ur_modular.UR2Arm``, ``panda_modular.Panda2Arm``) names robo-gym's joints (for
``fix_<joint>``), the limits, the default pose and the workspace. Where we differ from 2.1.0:
``docs/protocol.md``, "The envs: where they differ from 2.1.0".
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import fields
from typing import Any, ClassVar

import numpy as np
from gymnasium import spaces
from scipy.spatial.transform import Rotation

from robogym_ray.envs.arm_common import ArmTask
from robogym_ray.envs.base import StepInfo
from robogym_ray.envs.frames import box, frame_quat, frame_rotation, frame_xyz, in_frame, spherical
from robogym_ray.envs.outcomes import COLLISION, MAX_STEPS, SUCCESS
from robogym_ray.envs.pose_targets import (
    PoseTaskConfig,
    pose_from_user,
    positive,
    sample_target_pose,
)
from robogym_ray.errors import ConfigError
from robogym_ray.protocol import robot_server_pb2 as pb
from robogym_ray.protocol.client import RobotServerClient

DISTANCE_WEIGHT, ROTATION_WEIGHT = -0.005, -0.05
"""Per-step reward per metre of distance and per radian of rotation error (2.1.0's weights)."""
SUCCESS_REWARD, COLLISION_REWARD = 2.0, -1.0
"""The reward of a success / collision step (replaces the distance terms, as in 2.1.0)."""


def interp_normalize(q: np.ndarray, lower: np.ndarray, upper: np.ndarray) -> np.ndarray:
    """2.1.0's ``ManipulatorModel.normalize_joint_values``: ``np.interp`` of the limits onto
    [-1, 1], so positions beyond a limit saturate at +-1."""
    scaled = 2.0 * (np.asarray(q, np.float64) - lower) / (upper - lower) - 1.0
    return np.clip(scaled, -1.0, 1.0)


class ModularArmTask(ArmTask):
    """2.1.0's ``ManipulatorBaseEnv`` on the arm of the task class that follows in the MRO.

    Args:
        fix_<joint>: robo-gym's joint name (``fix_wrist_3``, ``fix_panda_joint7``): the joint
            is held at its start and leaves the action. Default: the binding's
            ``fixed_by_default``.
        joint_position: the start pose (rad, task order); default the binding's.
        joint_position_tolerance_normalized: normalised positions are observed within
            +-(1 + this) (default 0.1).
        rs_state_to_info: put the server's ``state_dict`` in every info as ``rs_state``.
        action_rate: actions per second (Hz); default the class's.
        max_velocity_scale_factor: the server's joint speed scale; default the class's.
        **kwargs: those of the arm's task class (``ur_model`` ...) and ``RobotServerEnv``'s.
    """

    robo_gym_joints: ClassVar[tuple[str, ...]]
    """robo-gym 2.1.0's joint names in task order (its ``fix_<name>`` keyword arguments)."""
    lower: np.ndarray
    upper: np.ndarray
    """Joint position limits (rad, task order) of robo-gym's robot model: class attributes, or
    instance ones that the arm's task class sets before this class's ``__init__`` reads them
    (the Panda's and the FR3's differ)."""
    default_joints: ClassVar[tuple[float, ...]]
    """Default ``joint_position`` (rad, task order)."""
    fixed_by_default: ClassVar[tuple[str, ...]] = ()
    """robo-gym names whose ``fix_<name>`` defaults to True."""
    fixable: ClassVar[bool] = True
    """False where 2.1.0's action node moves every joint whatever ``fix_<joint>`` says."""
    limit_status = SUCCESS

    def __init__(
        self,
        *,
        joint_position: Sequence[float] | None = None,
        joint_position_tolerance_normalized: float = 0.1,
        rs_state_to_info: bool = False,
        action_rate: float | None = None,
        max_velocity_scale_factor: float | None = None,
        **kwargs: Any,
    ) -> None:
        fixed = self._fixed_joints(kwargs)
        super().__init__(fixed_joints=fixed, **kwargs)
        self.joint_position = self.checked_pose(
            self.default_joints if joint_position is None else joint_position, "joint_position"
        )
        self.start_joints = self.joint_position.copy()
        self.tolerance = positive("joint_position_tolerance_normalized",
                                   joint_position_tolerance_normalized, zero_ok=True)  # fmt: skip
        self.rs_state_to_info = bool(rs_state_to_info)
        # Instance values shadow the class's: server_spec() reads them for the launch options.
        if action_rate is not None:
            self.action_rate = positive("action_rate", action_rate)
        if max_velocity_scale_factor is not None:
            self.velocity_scale = positive("max_velocity_scale_factor", max_velocity_scale_factor)
        self.action_space = self._action_space()
        self.last_action = np.zeros(self.action_space.shape)
        self.observation_space = box(*self._obs_bounds())

    def _fixed_joints(self, kwargs: dict[str, Any]) -> list[str]:
        """Pop robo-gym's ``fix_<joint>`` kwargs; the task-order names of the fixed joints."""
        if "fixed_joints" in kwargs:
            raise ConfigError("robo-gym 2.1.0's envs fix joints with fix_<joint>=True")
        given = {k[4:]: bool(kwargs.pop(k)) for k in list(kwargs) if k.startswith("fix_")}
        unknown = sorted(set(given) - set(self.robo_gym_joints))
        if unknown:
            raise ConfigError(f"unknown fix_{unknown[0]}; joints are {self.robo_gym_joints}")
        if given and not self.fixable:
            raise ConfigError(f"{type(self).__name__} moves every joint: no fix_<joint>")
        return [
            ours
            for name, ours in zip(self.robo_gym_joints, self.joint_names, strict=True)
            if self.fixable and given.get(name, name in self.fixed_by_default)
        ]

    def workspace(self) -> tuple[float, float]:
        """``(r, min_r)`` (m) of robo-gym's workspace half ball (the binding's; it comes after
        ``PoseTask`` in the MRO, so it is declared here)."""
        raise NotImplementedError

    def checked_pose(self, q: Sequence[float], what: str) -> np.ndarray:
        """``q`` as joint positions: one per joint, finite and within the limits."""
        pose = np.asarray(q, dtype=np.float64).reshape(-1)
        if pose.shape != self.lower.shape or not np.all(np.isfinite(pose)):
            raise ConfigError(f"{what} needs {self.lower.size} finite joint positions, got {q!r}")
        if np.any(pose < self.lower) or np.any(pose > self.upper):
            raise ConfigError(f"{what} {pose.tolist()} is outside the joint limits")
        return pose

    # -- spaces ----------------------------------------------------------------------------
    def _action_space(self) -> spaces.Box:
        return self.action_space  # the arm's: [-1, 1] per moving joint

    def _joint_bounds(self) -> tuple[list[float], list[float]]:
        """Normalised positions (+-(1 + tolerance)) then velocities (free)."""
        n, pos = self.lower.size, 1.0 + self.tolerance
        return [-pos] * n + [-np.inf] * n, [pos] * n + [np.inf] * n

    def _obs_bounds(self) -> tuple[list[float], list[float]]:
        return self._joint_bounds()

    def normalized(self, msg: pb.State) -> np.ndarray:
        """Normalised joint positions then velocities (2.1.0's ``ManipulatorObservationNode``)."""
        q = interp_normalize(self.joints(msg), self.lower, self.upper)
        return np.concatenate([q, self.velocities(msg)])

    # -- episode ---------------------------------------------------------------------------
    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, StepInfo]:
        obs, info = super().reset(seed=seed, options=options)
        assert self._last_msg is not None
        info.update(self._info(self._last_msg))
        return obs, info

    def _reset_server(self, client: RobotServerClient, options: Mapping[str, Any]) -> pb.State:
        start = self._start(options)  # before the target: 2.1.0's order of random draws
        strings, floats = self._prepare(options)
        self.last_action = np.zeros(self.action_space.shape)
        return self.set_joints(client, start, strings, floats)

    def _start(self, options: Mapping[str, Any]) -> np.ndarray:
        q = options.get("joint_positions")
        return self.joint_position.copy() if q is None else self.checked_pose(q, "joint_positions")

    def _prepare(self, options: Mapping[str, Any]) -> tuple[dict[str, str], dict[str, float]]:
        """What the episode adds to SetState (string and float params)."""
        return {}, {}

    def _send(self, client: RobotServerClient, action: np.ndarray) -> pb.State:
        self.last_action = np.asarray(action, dtype=np.float64)
        return super()._send(client, action)

    def _to_obs(self, msg: pb.State) -> np.ndarray:
        return self.normalized(msg).astype(np.float32)

    def _info(self, msg: pb.State) -> StepInfo:
        return {"rs_state": dict(msg.state_dict)} if self.rs_state_to_info else {}

    def _evaluate(
        self, msg: pb.State, obs: np.ndarray, action: np.ndarray
    ) -> tuple[float, str | None, StepInfo]:
        return 0.0, (COLLISION if self.collided(msg) else None), self._info(msg)


class PoseTask(ModularArmTask):
    """2.1.0's ``ManipulatorEePosEnv``: reach a target pose. Keyword arguments: the fields of
    ``PoseTaskConfig`` (defaults: those, updated by the class's ``pose_defaults``) and
    ``ModularArmTask``'s. Reset options ``joint_positions``, ``ee_target_pose`` and
    ``randomize_start`` override the keyword arguments for one episode.
    """

    rs_mode = "1object"
    limit_status = MAX_STEPS
    pose_defaults: ClassVar[Mapping[str, Any]] = {}
    """A subclass's defaults for ``PoseTaskConfig`` (2.1.0's ``kwargs.setdefault`` calls)."""

    def __init__(self, **kwargs: Any) -> None:
        names = {f.name for f in fields(PoseTaskConfig)}
        given = {k: kwargs.pop(k) for k in list(kwargs) if k in names}
        self.pose_cfg = PoseTaskConfig(**{**self.pose_defaults, **given})
        self.target_pose = np.array([0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0])
        self.target = self.target_pose[:3].copy()
        self._continue_from: np.ndarray | None = None
        super().__init__(**kwargs)
        offset = self.pose_cfg.random_joint_offset
        if offset is not None and np.asarray(offset).shape != self.lower.shape:
            raise ConfigError(f"random_joint_offset needs {self.lower.size} values, got {offset}")

    # -- episode ---------------------------------------------------------------------------
    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, StepInfo]:
        # A seeded reset reproduces its episode (Gymnasium's convention; evaluations pair
        # policies by reset seed); an unseeded one, as rollout workers reset, continues from
        # the last pose as 2.1.0 does.
        if seed is not None:
            self._continue_from = None
        return super().reset(seed=seed, options=options)

    def _start(self, options: Mapping[str, Any]) -> np.ndarray:
        cfg, last = self.pose_cfg, self._continue_from
        self._continue_from = None
        if options.get("joint_positions") is not None:
            return super()._start(options)
        if last is not None and (cfg.continue_on_success or cfg.continue_except_collision):
            return last
        if options.get("randomize_start", cfg.randomize_start):
            if cfg.random_joint_offset is None:
                raise ConfigError("randomize_start needs random_joint_offset")
            offset = np.asarray(cfg.random_joint_offset, dtype=np.float64)
            q = self.np_random.uniform(self.joint_position - offset, self.joint_position + offset)
            return np.clip(q, self.lower, self.upper)  # our servers refuse goals past a limit
        return self.joint_position.copy()

    def _prepare(self, options: Mapping[str, Any]) -> tuple[dict[str, str], dict[str, float]]:
        pose = options.get("ee_target_pose", self.pose_cfg.ee_target_pose)
        if pose is None:
            self.target_pose = sample_target_pose(self.np_random, self.pose_cfg, self.workspace())
        else:
            self.target_pose = pose_from_user(pose)
        self.target = self.target_pose[:3].copy()
        floats = {f"object_0_{a}": float(v) for a, v in zip("xyz", self.target, strict=True)}
        return {"object_0_function": "fixed_position"}, floats

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, StepInfo]:
        out = super().step(action)
        status = out[4].get("final_status")
        # 2.1.0 remembers the pose after a success, and after any end but a collision when
        # continue_except_collision (its step limit is such an end); never after a restart.
        if status == SUCCESS or (self.pose_cfg.continue_except_collision and status == MAX_STEPS):
            assert self._last_msg is not None
            self._continue_from = self.joints(self._last_msg)
        return out

    # -- observation and reward -------------------------------------------------------------
    def _obs_bounds(self) -> tuple[list[float], list[float]]:
        """2.1.0's ``ManipulatorEePosObservationNode`` + ``LastActionObservationNode``."""
        low, high = self._joint_bounds()
        quat = [1.0] * 4 if self.pose_cfg.ee_rotation_matters else []
        pose_hi = [np.inf] * 3 + quat
        space = self.action_space
        return (
            [-np.inf] * 3 + low + [-v for v in pose_hi] * 2 + space.low.tolist(),
            [np.inf] * 3 + high + pose_hi * 2 + space.high.tolist(),
        )

    def _to_obs(self, msg: pb.State) -> np.ndarray:
        sd = msg.state_dict
        rotation = self.pose_cfg.ee_rotation_matters
        parts = [spherical(in_frame(sd, self.target, "ee")), self.normalized(msg), self.target]
        parts += [self.target_pose[3:]] if rotation else []
        parts += [frame_xyz(sd, "ee")]
        parts += [frame_quat(sd, "ee")] if rotation else []
        parts += [self.last_action]
        return np.concatenate(parts).astype(np.float32)

    def _evaluate(
        self, msg: pb.State, obs: np.ndarray, action: np.ndarray
    ) -> tuple[float, str | None, StepInfo]:
        """2.1.0's ``ManipulatorEePosRewardNode``: the distance is the server's object 0 to the
        end effector; success and collision replace the reward (a collision wins)."""
        sd, cfg = msg.state_dict, self.pose_cfg
        target = frame_xyz(sd, "object_0")
        distance = float(np.linalg.norm(target - frame_xyz(sd, "ee")))
        reward = DISTANCE_WEIGHT * distance
        info: StepInfo = {**self._info(msg), "dist_coord": distance}
        rotation_ok = True
        if cfg.ee_rotation_matters:
            goal = Rotation.from_quat(self.target_pose[3:])
            error = float((frame_rotation(sd, "ee") * goal.inv()).magnitude())
            reward += ROTATION_WEIGHT * error
            rotation_ok = error < cfg.ee_rotation_threshold
            info.update(dist_rot=error, target_rot=self.target_pose[3:].copy())
        info["target_coord"] = target
        status = None
        if rotation_ok and distance <= cfg.ee_distance_threshold:
            reward, status = SUCCESS_REWARD, SUCCESS
        if self.collided(msg):
            reward, status = COLLISION_REWARD, COLLISION
        return reward, status, info
