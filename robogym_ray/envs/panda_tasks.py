"""Franka Emika Panda tasks of robo-gym 2.1.0: ``EmptyEnvironmentPanda`` and
``EndEffectorPositioningPanda`` (robo-gym's ``EmptyEnvironmentPandaSim-v0`` and
``EndEffectorPositioningPandaSim-v0``, and their ``Rob`` variants), and the same tasks on the
Franka Research 3 (``panda_model="fr3"``: ids ``...FR3Sim-v0`` / ``...FR3Rob-v0``).

Joints are in the Panda's order 1-7 everywhere, on the wire too. Positions are normalised as
robo-gym's ``ManipulatorModel`` does: ``np.interp`` between the (asymmetric) limits of the arm
model and [-1, 1], so values beyond a limit saturate at +-1 in both directions. The FR3's
limits are not the Panda's, so one normalised action means other joint targets on each arm.
robo-gym's start pose and target box suit both arms: the start lies within the FR3's limits too
(its joint 6 starts at 0.4398 rad, joint 4 ends at -0.1169 rad), and the arms' kinematics are
the same.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any, ClassVar

import numpy as np
from gymnasium import spaces

from robogym_ray.envs.arm_common import ArmTask
from robogym_ray.envs.base import RobotServerEnv, StepInfo
from robogym_ray.envs.frames import box, frame_xyz, in_frame, spherical
from robogym_ray.envs.modular import interp_normalize
from robogym_ray.envs.outcomes import COLLISION, SUCCESS
from robogym_ray.envs.render import RenderConfig
from robogym_ray.envs.render.canvas import Canvas, PerspectiveProjection, ViewCamera
from robogym_ray.errors import ConfigError
from robogym_ray.protocol import robot_server_pb2 as pb
from robogym_ray.protocol.client import RobotServerClient
from robogym_ray.robots.panda.model import (
    JOINT_NAMES,
    LABELS,
    LIMITS,
    PANDA_LIMITS,
    ArmLimits,
    forward_kinematics,
)
from robogym_ray.robots.panda.state import POSITION_KEYS, RS_MODE_KEYS, VELOCITY_KEYS
from robogym_ray.text import did_you_mean

DEFAULT_JOINTS = (-0.018, -0.76, 0.02, -2.342, 0.03, 1.541, 0.753)
"""robo-gym 2.1.0's default Panda start (rad), close to the 'ready' pose; within the limits of
both arms, so the FR3's tasks start there too."""
START_SPREAD = (1.5, 0.25, 0.5, 1.0, 0.4, 3.14, 1.0)
"""robo-gym 2.1.0's ``random_joint_offset`` half-widths (rad) for ``randomize_start``."""
TARGET_BOX = ((0.35, 0.65), (-0.2, 0.2), (0.15, 0.5))
"""x, y, z ranges (m, ``world``) of the end-effector targets."""
POSITION_TOLERANCE = 0.1
"""Normalised positions are observed within +-(1 + this) (robo-gym's default tolerance)."""


def normalize(q: np.ndarray, limits: ArmLimits = PANDA_LIMITS) -> np.ndarray:
    """Joint positions (rad) -> [-1, 1] over the arm's ``limits``, saturating beyond them."""
    return interp_normalize(q, limits.lower, limits.upper)


def denormalize(a: np.ndarray, limits: ArmLimits = PANDA_LIMITS) -> np.ndarray:
    """[-1, 1] -> joint positions (rad) over the arm's ``limits``, saturating beyond +-1."""
    lower, upper = limits.lower, limits.upper
    return lower + (np.clip(np.asarray(a, np.float64), -1.0, 1.0) + 1.0) / 2.0 * (upper - lower)


class PandaTask(ArmTask):
    """A task on a Franka arm: absolute joint targets, normalised, some joints fixed.

    Args:
        panda_model: ``panda`` or ``fr3``: the arm (its joint limits and its robot server).
        fixed_joints: joint names (``panda_joint1`` ...) the agent does not move; each removes
            one action dimension and is held at its start position. Default: ``panda_joint7``.
        **kwargs: see ``RobotServerEnv``.
    """

    metadata: ClassVar[dict[str, Any]] = {**RobotServerEnv.metadata, "render_fps": 30}
    joint_names = JOINT_NAMES
    mode_keys = RS_MODE_KEYS
    position_keys = POSITION_KEYS
    velocity_keys = VELOCITY_KEYS
    world: ClassVar[str] = "empty_no_gravity.world"
    velocity_scale: ClassVar[float] = 0.2
    action_rate: ClassVar[float] = 30.0
    max_episode_steps = 300

    def __init__(
        self,
        *,
        panda_model: str = "panda",
        fixed_joints: Sequence[str] | None = None,
        **kwargs: Any,
    ) -> None:
        super().__init__(**kwargs)
        if panda_model not in LIMITS:
            hint = did_you_mean(panda_model, LIMITS)
            raise ConfigError(
                f"unknown panda_model {panda_model!r}{hint}; choose from {list(LIMITS)}"
            )
        self.panda_model = panda_model
        self.limits = LIMITS[panda_model]
        # Instance values: the modular envs (ModularArmTask) read the arm's limits from them.
        self.lower, self.upper = self.limits.lower, self.limits.upper
        self.label = LABELS[panda_model]
        fixed = tuple(("panda_joint7",) if fixed_joints is None else fixed_joints)
        unknown = set(fixed) - set(JOINT_NAMES)
        if unknown:
            raise ConfigError(f"fixed_joints {sorted(unknown)} unknown; joints: {JOINT_NAMES}")
        self.active = np.array([j not in fixed for j in JOINT_NAMES])
        self.action_space = spaces.Box(-1.0, 1.0, shape=(int(self.active.sum()),), dtype=np.float32)
        self.keys = frozenset(RS_MODE_KEYS[self.rs_mode])
        self.start_joints = np.array(DEFAULT_JOINTS)

    def server_spec(self) -> tuple[str, str | None, dict[str, str]]:
        """The launch arguments robo-gym 2.1.0 sends (minus the GUI switches)."""
        options = {
            "world_name": self.world,
            "reference_frame": "world",
            "max_velocity_scale_factor": str(self.velocity_scale),
            "action_cycle_rate": str(self.action_rate),
            "rs_mode": self.rs_mode,
            "action_mode": "abs_pos",
        }
        if self.rs_mode == "1object":
            options.update(objects_controller="true", n_objects="1.0", object_0_frame="target")
            options["object_0_model_name"] = "sphere50_no_collision"
        return self.panda_model, None, options

    # -- wire ------------------------------------------------------------------------------
    def set_joints(
        self,
        client: RobotServerClient,
        joints: np.ndarray,
        string_params: Mapping[str, str] | None = None,
        float_params: Mapping[str, float] | None = None,
    ) -> pb.State:
        """robo-gym 2.1.0's SetState (the seven positions only), then GetState and checks."""
        goal = {k: float(q) for k, q in zip(POSITION_KEYS, joints, strict=True)}
        return self._set_joint_goal(client, goal, joints, string_params, float_params)

    def joint_targets(self, action: np.ndarray) -> np.ndarray:
        """Active joints from ``action``, fixed ones at their start; denormalised to rad."""
        full = normalize(self.start_joints, self.limits)
        full[self.active] = action
        return denormalize(full, self.limits)

    def _send(self, client: RobotServerClient, action: np.ndarray) -> pb.State:
        return self.checked(client.send_action_get_state(self.joint_targets(action)))

    # -- reading a state -------------------------------------------------------------------
    def joint_obs(self, msg: pb.State) -> np.ndarray:
        return np.concatenate([normalize(self.joints(msg), self.limits), self.velocities(msg)])

    def _draw(self, msg: pb.State, cfg: RenderConfig) -> np.ndarray:
        return draw_panda(
            self.joints(msg),
            cfg,
            target=getattr(self, "target", None),
            collided=msg.state_dict.get("in_collision", 0.0) >= 0.5,
            caption=f"{type(self).__name__} ({self.label})  step {self.elapsed_steps}",
        )


def joint_bounds() -> tuple[list[float], list[float]]:
    """Normalised positions (7, +-1.1) then velocities (7, free)."""
    pos = 1.0 + POSITION_TOLERANCE
    return [-pos] * 7 + [-np.inf] * 7, [pos] * 7 + [np.inf] * 7


class EmptyEnvironmentPanda(PandaTask):
    """robo-gym 2.1.0's ``EmptyEnvironmentPandaSim-v0``, on the Panda or the FR3: move freely,
    do not collide.

    ## Action space
    ``Box(-1, 1, (6,), float32)`` (panda_joint7 fixed at its start; see ``fixed_joints``):
    normalised absolute joint targets, ``-1`` / ``1`` = the arm's lower / upper joint limit. 30
    actions per second; joint speeds at most 0.2 of the arm's published limits.

    ## Observation space
    ``Box((14,), float32)``: normalised joint positions (7, +-1.1), joint velocities (7, free).

    ## Reward
    0 on every step.

    ## Episode end
    terminated: ``collision`` (self, ground; Sim only). Truncated after 300 steps with
    final_status ``success`` (robo-gym reports done), or ``server_restarted``.

    ## Reset
    Joints ``(-0.018, -0.76, 0.02, -2.342, 0.03, 1.541, 0.753)`` (option ``joint_positions``).

    ## Arguments
    ``panda_model`` (``panda``, or ``fr3`` for the ``...FR3`` ids), ``fixed_joints`` and
    ``RobotServerEnv``'s.
    """

    limit_status = SUCCESS

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self.observation_space = box(*joint_bounds())

    def _reset_server(self, client: RobotServerClient, options: Mapping[str, Any]) -> pb.State:
        joints = options.get("joint_positions")
        return self.set_joints(client, np.array(DEFAULT_JOINTS if joints is None else joints))

    def _to_obs(self, msg: pb.State) -> np.ndarray:
        return self.joint_obs(msg).astype(np.float32)

    def _evaluate(
        self, msg: pb.State, obs: np.ndarray, action: np.ndarray
    ) -> tuple[float, str | None, StepInfo]:
        info: StepInfo = {"rs_state": dict(msg.state_dict)}
        return 0.0, (COLLISION if self.collided(msg) else None), info


class EndEffectorPositioningPanda(PandaTask):
    """robo-gym 2.1.0's ``EndEffectorPositioningPandaSim-v0``, on the Panda or the FR3: bring
    ``panda_hand`` to a point.

    ## Action space
    ``Box(-1, 1, (6,), float32)``, as ``EmptyEnvironmentPanda``.

    ## Observation space
    ``Box((29,), float32)``

    | index | meaning | bounds |
    |---|---|---|
    | 0-2 | target in the hand frame, ``[r, arccos(z/r), atan2(y, x)]`` | free |
    | 3-9 | joint positions, normalised | [-1.1, 1.1] |
    | 10-16 | joint velocities (rad/s) | free |
    | 17-19 | target xyz (``world``) | free |
    | 20-22 | hand xyz (``world``) | free |
    | 23-28 | the previous action | [-1, 1] |

    ## Reward
    ``-0.005 * distance`` per step (hand -> target, m); 2 instead when the distance <= 0.1 m
    (success); -1 instead on a collision.

    ## Episode end
    terminated: ``success``, ``collision`` (Sim only; a collision wins over success);
    truncated: ``max_steps_exceeded`` after 300 steps (robo-gym: done), ``server_restarted``.

    ## Reset
    Joints as ``EmptyEnvironmentPanda`` (``randomize_start`` adds U(+-``START_SPREAD``), clipped
    into the limits); the target uniform in x 0.35-0.65, y -0.2-0.2, z 0.15-0.5 m, sent as object
    0 (``fixed_position``) on robo-gym's tabletop. Options: ``joint_positions``,
    ``ee_target_pose``, ``randomize_start``.

    ## Arguments
    As ``EmptyEnvironmentPanda``.
    """

    rs_mode = "1object"
    world = "tabletop_sphere50_no_collision_no_gravity.world"
    success_distance: ClassVar[float] = 0.1

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        low, high = joint_bounds()
        n = int(self.active.sum())
        self.observation_space = box(
            [-np.inf] * 3 + low + [-np.inf] * 6 + [-1.0] * n,
            [np.inf] * 3 + high + [np.inf] * 6 + [1.0] * n,
        )
        self.target = np.zeros(3)
        self.previous_action = np.zeros(n)

    def _reset_server(self, client: RobotServerClient, options: Mapping[str, Any]) -> pb.State:
        if options.get("joint_positions") is not None:
            start = np.asarray(options["joint_positions"], dtype=np.float64)
        elif options.get("randomize_start", False):
            spread = np.asarray(START_SPREAD)
            start = np.array(DEFAULT_JOINTS) + self.np_random.uniform(-spread, spread)
            start = np.clip(start, self.lower, self.upper)
        else:
            start = np.array(DEFAULT_JOINTS)
        if options.get("ee_target_pose") is not None:
            self.target = np.asarray(options["ee_target_pose"], dtype=np.float64)[:3]
        else:
            self.target = np.array([self.np_random.uniform(lo, hi) for lo, hi in TARGET_BOX])
        self.previous_action = np.zeros(self.action_space.shape)
        params = {f"object_0_{a}": float(v) for a, v in zip("xyz", self.target, strict=True)}
        return self.set_joints(client, start, {"object_0_function": "fixed_position"}, params)

    def _send(self, client: RobotServerClient, action: np.ndarray) -> pb.State:
        self.previous_action = np.asarray(action, dtype=np.float64)
        return super()._send(client, action)

    def _to_obs(self, msg: pb.State) -> np.ndarray:
        sd = msg.state_dict
        parts = [
            spherical(in_frame(sd, self.target, "ee")),
            self.joint_obs(msg),
            self.target,
            frame_xyz(sd, "ee"),
            self.previous_action,
        ]
        return np.concatenate(parts).astype(np.float32)

    def _evaluate(
        self, msg: pb.State, obs: np.ndarray, action: np.ndarray
    ) -> tuple[float, str | None, StepInfo]:
        sd = msg.state_dict
        distance = float(np.linalg.norm(frame_xyz(sd, "object_0") - frame_xyz(sd, "ee")))
        info: StepInfo = {"dist_coord": distance, "target_coord": self.target.copy()}
        if self.collided(msg):
            return -1.0, COLLISION, info
        if distance <= self.success_distance:
            return 2.0, SUCCESS, info
        return -0.005 * distance, None, info


def draw_panda(
    q: np.ndarray,
    cfg: RenderConfig,
    *,
    target: np.ndarray | None = None,
    collided: bool = False,
    caption: str = "",
) -> np.ndarray:
    """A ``uint8`` H x W x 3 frame: the arm's skeleton from forward kinematics, the target."""
    camera = cfg.camera if isinstance(cfg.camera, ViewCamera) else ViewCamera((1.6, -1.9, 1.3))
    project = PerspectiveProjection(camera, cfg.width, cfg.height)
    canvas = Canvas(cfg)
    frames = forward_kinematics(q)
    names = ("panda_link1", "panda_link3", "panda_link4", "panda_link5", "panda_link7")
    points = np.array([np.zeros(3)] + [frames[n][0] for n in (*names, "panda_link8")])
    px, depth = project(points)
    color = (220, 40, 40) if collided else (110, 130, 160)
    if np.all(depth > 0):
        for i in range(len(points) - 1):
            canvas.line(px[i : i + 2], color, width=max(2, int(project.focal * 0.05 / depth[i])))
        for i in range(len(points)):
            canvas.disc(px[i], max(2.0, project.focal * 0.035 / depth[i]), (50, 55, 70))
    if target is not None:
        tpx, tdepth = project(np.asarray(target, float)[None])
        if tdepth[0] > 0:
            canvas.disc(tpx[0], max(2.0, project.focal * 0.03 / tdepth[0]), (40, 170, 60))
    if caption:
        canvas.text((6, 4), caption)
    return canvas.array()
