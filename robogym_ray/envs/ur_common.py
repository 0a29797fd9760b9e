"""Shared machinery of the UR tasks: key sets, joint order and scaling, SetState, stepping.

Joint vectors are in *env order* ``[base (shoulder_pan), shoulder (lift), elbow, wrist_1,
wrist_2, wrist_3]`` everywhere in the envs; they are swapped to ROS order (indices 0 and 2) only
on the wire (spec c.2.2). The server's ``state_dict`` is read by name.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any, ClassVar

import numpy as np
from gymnasium import spaces

from robogym_ray.envs.arm_common import ArmTask
from robogym_ray.envs.base import RobotServerEnv
from robogym_ray.envs.frames import frame_xyz
from robogym_ray.envs.render import RenderConfig
from robogym_ray.envs.render.ur import draw_ur, stand_of
from robogym_ray.errors import ConfigError
from robogym_ray.protocol import robot_server_pb2 as pb
from robogym_ray.protocol.client import RobotServerClient
from robogym_ray.robots.ur.geometry import POSITION_LIMITS, ROS_FROM_ENV, UR_MODELS
from robogym_ray.robots.ur.state import JOINT_KEYS, POSITION_KEYS, RS_MODE_KEYS, VELOCITY_KEYS
from robogym_ray.text import did_you_mean

# The arm's geometry, limits and key names are the robot's (robots/ur/), defined there once.
JOINTS = JOINT_KEYS
JOINT_MAX = POSITION_LIMITS
"""Position limits (rad, symmetric), env order; identical for all seven models (spec e.2)."""


KEYS: dict[str, frozenset[str]] = {
    mode: frozenset(RS_MODE_KEYS[mode]) for mode in ("only_robot", "1object", "1moving2points")
}
"""The exact ``state_dict`` key set of each rs_mode (spec c.2.1)."""


def normalize_joints(q: np.ndarray) -> np.ndarray:
    """robo-gym's normalisation q/|min| (q <= 0) or q/max; the limits are symmetric."""
    return np.asarray(q, dtype=np.float64) / JOINT_MAX


def to_ros(q_env: np.ndarray) -> np.ndarray:
    """Env -> ROS order ``[elbow, shoulder_lift, shoulder_pan, wrist_1, wrist_2, wrist_3]``."""
    return np.asarray(q_env)[list(ROS_FROM_ENV)]


class URTask(ArmTask):
    """A task on a UR arm. Subclasses set the class attributes and the task methods.

    Args:
        ur_model: ur3, ur3e, ur5, ur5e, ur10, ur10e or ur16e.
        fixed_joints: env-order joint names the agent does not move (e.g. ``("wrist_3",)``);
            each removes one action dimension. Default: the class's ``default_fixed``.
        **kwargs: see ``RobotServerEnv``.
    """

    metadata: ClassVar[dict[str, Any]] = {**RobotServerEnv.metadata, "render_fps": 20}
    """Frames at the action rate (20 Hz)."""
    joint_names = JOINTS
    mode_keys = RS_MODE_KEYS
    position_keys = POSITION_KEYS
    velocity_keys = VELOCITY_KEYS
    scene: ClassVar[str] = "empty"
    velocity_scale: ClassVar[float] = 0.2
    action_rate: ClassVar[float] = 20.0
    default_fixed: ClassVar[tuple[str, ...]] = ("wrist_3",)
    reset_joints: ClassVar[tuple[float, ...]] = (0.0, -2.5, 1.5, 0.0, -1.4, 0.0)

    def __init__(
        self, *, ur_model: str = "ur5", fixed_joints: Sequence[str] | None = None, **kwargs: Any
    ) -> None:
        super().__init__(**kwargs)
        if ur_model not in UR_MODELS:
            hint = did_you_mean(ur_model, UR_MODELS)
            known = sorted(UR_MODELS)
            raise ConfigError(f"unknown ur_model {ur_model!r}{hint}; choose from {known}")
        self.ur_model = ur_model
        self.model = UR_MODELS[ur_model]
        fixed = tuple(self.default_fixed if fixed_joints is None else fixed_joints)
        unknown = set(fixed) - set(JOINTS)
        if unknown:
            raise ConfigError(f"fixed_joints {sorted(unknown)} unknown; joints are {JOINTS}")
        self.active = np.array([j not in fixed for j in JOINTS])
        self.action_space = spaces.Box(-1.0, 1.0, shape=(int(self.active.sum()),), dtype=np.float32)
        self.keys = KEYS[self.rs_mode]
        self.start_joints = np.array(self.reset_joints)
        self.last_rs_state: dict[str, float] = {}

    def server_spec(self) -> tuple[str, str | None, dict[str, str]]:
        options = {
            "rs_mode": self.rs_mode,
            "reference_frame": "base_link",
            "max_velocity_scale_factor": str(self.velocity_scale),
            # "20" as robo-gym 2.0.1 sends it; a rate a user sets (12.5 Hz) is kept whole.
            "action_cycle_rate": f"{self.action_rate:g}",
        }
        if self.rs_mode != "only_robot":
            options.update(objects_controller="true", n_objects="1.0", object_0_frame="target")
        return self.ur_model, self.scene, options

    # -- wire ------------------------------------------------------------------------------
    def set_joints(
        self,
        client: RobotServerClient,
        joints: np.ndarray,
        string_params: Mapping[str, str] | None = None,
        float_params: Mapping[str, float] | None = None,
    ) -> pb.State:
        """robo-gym's UR SetState (all keys 0 but the joint goal), then GetState and checks."""
        state_dict = dict.fromkeys(self.keys, 0.0)
        state_dict.update(zip(POSITION_KEYS, (float(q) for q in joints), strict=True))
        return self._set_joint_goal(client, state_dict, joints, string_params, float_params)

    def joint_targets(self, action: np.ndarray) -> np.ndarray:
        """robo-gym's UR map: the action times the limits, fixed joints at their start."""
        return self.full_action(action, normalize_joints(self.start_joints)) * JOINT_MAX

    def _send(self, client: RobotServerClient, action: np.ndarray) -> pb.State:
        """The targets of ``joint_targets`` (every UR task's map from actions to joints)."""
        return self.send_joint_targets(client, self.joint_targets(action))

    def send_joint_targets(self, client: RobotServerClient, q_env: np.ndarray) -> pb.State:
        """Absolute joint targets (rad, env order) through SendActionGetState (ROS order)."""
        return self.checked(client.send_action_get_state(to_ros(q_env)))

    def checked(self, msg: pb.State) -> pb.State:
        """``ArmTask.checked``, keeping the state for ``last_rs_state``."""
        msg = super().checked(msg)
        self.last_rs_state = dict(msg.state_dict)
        return msg

    def _draw(self, msg: pb.State, cfg: RenderConfig) -> np.ndarray:
        sd = msg.state_dict
        # The positioning tasks' object 0 is their target; the avoidance tasks' an obstacle.
        target = getattr(self, "target", None)
        moving = target is None and "object_0_to_ref_translation_x" in sd
        caption = f"{type(self).__name__} ({self.ur_model})  step {self.elapsed_steps}"
        return draw_ur(
            self.ur_model,
            self.joints(msg),
            cfg,
            target=target,
            objects=[frame_xyz(sd, "object_0")] if moving else [],
            collided=sd.get("in_collision", 0.0) >= 0.5,
            stand=stand_of(self.server_spec()),  # the scene's ground and tables, where they are
            caption=caption,
        )

    def full_action(self, action: np.ndarray, fill: np.ndarray) -> np.ndarray:
        """Six values in env order: ``action`` on the active joints, ``fill`` on the fixed ones."""
        full = np.array(fill, dtype=np.float64)
        full[self.active] = action
        return full

    def random_start(self, spread: Sequence[float]) -> np.ndarray:
        """``reset_joints`` plus U(-spread, spread) per joint (robo-gym's ``randomize_start``)."""
        spread_arr = np.asarray(spread, dtype=np.float64)
        return np.array(self.reset_joints) + self.np_random.uniform(-spread_arr, spread_arr)


def joint_obs_bounds(n_norm: int, n_vel: int) -> tuple[list[float], list[float]]:
    """Bounds of ``n_norm`` normalised positions (+-1.1) then ``n_vel`` velocities (free)."""
    return [-1.1] * n_norm + [-np.inf] * n_vel, [1.1] * n_norm + [np.inf] * n_vel
