"""The simulated Franka Emika Panda behind robo-gym-robot-servers 2.1.0's Panda contract.

========================  ==================================================================
wire                      meaning
========================  ==================================================================
SendAction                7 floats, joint order 1-7: absolute targets (abs_pos) within the
                          joint limits, or deltas (delta_pos) no larger than a joint's range
SetState ``state_dict``   ``joint1_position`` ... ``joint7_position`` (required, within the
                          limits); any other known key is ignored, unknown keys are an error
SetState params           ``object_0_function`` + ``object_0_*`` floats (rs_mode 1object)
GetState                  the rs_mode's exact key set + flat list (``state``)
========================  ==================================================================

Differences from the ROS/Gazebo server, all deliberate:

* The controller is kinematic (``controller``); efforts are reported as 0 (no dynamics).
* SetState *places* the arm at the goal (velocity 0) instead of driving it there for 3 s.
* Collisions: PyBullet contacts of links 1-7 and the hand/fingers (against the ground, the
  table, or non-adjacent links) after every tick in which the arm moved, latched until the next
  SetState, like the Gazebo contact sensors the bridge listens to.
"""

from __future__ import annotations

import copy
from collections.abc import Iterable, Mapping

import numpy as np
import pybullet as p

from robogym_ray.errors import InvalidActionError, InvalidStateError
from robogym_ray.robots.base import SimRobot, StateRequest, StateSnapshot
from robogym_ray.robots.command_handler import CommandHandlerConfig
from robogym_ray.robots.objects import ObjectTrajectory, build_trajectory, parked
from robogym_ray.robots.panda.config import SCENES, PandaConfig, parse_options
from robogym_ray.robots.panda.controller import JointPositionController
from robogym_ray.robots.panda.model import (
    JOINT_NAMES,
    LINK_NAMES,
    LOWER,
    MAX_VELOCITY,
    UPPER,
    urdf_path,
)
from robogym_ray.robots.panda.state import (
    ALL_KEYS,
    N_OBJECTS,
    POSITION_KEYS,
    compose_state,
    sensor_groups,
)
from robogym_ray.robots.sim import PyBulletWorld
from robogym_ray.robots.validation import preview

LIMIT_TOLERANCE = 1e-4
"""Slack on position limits (rad): float32 on the wire rounds 2.8973 up by ~1e-7."""
OBJECT_RADIUS = 0.025
_IDENTITY = (0.0, 0.0, 0.0, 1.0)


def make_panda(
    model: str, scene: str | None, seed: int | None, options: Mapping[str, str]
) -> PandaArm:
    """Registry factory: a simulated Panda configured by launch-style ``options``."""
    return PandaArm(parse_options(model, scene, options), seed=seed)


class PandaArm(SimRobot):
    """One Panda (arm, hand, open fingers) and its scene in a PyBullet DIRECT world."""

    name = "panda"

    def __init__(self, config: PandaConfig, seed: int | None = None) -> None:
        self.config = config
        self.handler_config = CommandHandlerConfig(
            action_cycle=config.action_cycle, actuation_cycle=config.actuation_cycle
        )
        self.sensor_periods = {}
        self.groups = sensor_groups(config.rs_mode)
        self._rng = np.random.default_rng(seed)
        self._controller = JointPositionController(
            config.max_velocity_scale_factor * MAX_VELOCITY, LOWER, UPPER
        )
        self._world = PyBulletWorld()
        self._build_scene()
        self.time = 0.0
        """Sim time (s), advanced only by ``advance``."""
        n_objects = N_OBJECTS[config.rs_mode]
        self._objects: list[ObjectTrajectory] = [parked(i) for i in range(n_objects)]
        self._object_start = 0.0
        self._object_index = [-1] * n_objects
        self._last_command: np.ndarray | None = None
        self.in_collision = False
        self._controller.reset(np.clip(np.zeros(7), LOWER, UPPER))
        self._sync_joints()
        self._update_objects()
        self._check_collision()

    # -- scene ----------------------------------------------------------------------------------
    def _build_scene(self) -> None:
        world, scene = self._world, SCENES[self.config.scene]
        ground = world.add_plane("ground")
        world.client.resetBasePositionAndOrientation(ground, [0, 0, scene.ground_z], _IDENTITY)
        if scene.table:
            world.add_box("table", (0.635, 0.45, 0.5), (0.4, 0.0, -0.5))
        flags = p.URDF_USE_SELF_COLLISION | p.URDF_USE_SELF_COLLISION_EXCLUDE_PARENT
        self._uid = world.load_urdf("robot", urdf_path(), (0.0, 0.0, 0.0), flags=flags)
        index = {}
        for j in range(world.client.getNumJoints(self._uid)):
            info = world.client.getJointInfo(self._uid, j)
            index[info[1].decode()] = j
            index[info[12].decode()] = j  # child link index == joint index in PyBullet
        self._joint_ids = [index[n] for n in JOINT_NAMES]
        # Contact sensors: links 1-7 and the hand with its fingers (shapes of panda_link8).
        self._sensor_links = frozenset(index[n] for n in (*LINK_NAMES, "panda_link8"))
        self._ee_link = index[self.config.ee_frame]
        self._object_uids = [
            world.add_sphere(f"object_{i}", OBJECT_RADIUS, (float(i), 0.0, 3.0), collision=False)
            for i in range(N_OBJECTS[self.config.rs_mode])
        ]

    def _sync_joints(self) -> None:
        q = self._controller.position.reshape(7, 1).tolist()
        self._world.client.resetJointStatesMultiDof(self._uid, self._joint_ids, q)

    # -- actions --------------------------------------------------------------------------------
    def validate_action(self, action: np.ndarray) -> np.ndarray:
        a = np.asarray(action, dtype=np.float64).reshape(-1)
        if a.shape != (7,):
            raise InvalidActionError(
                f"Panda action must have 7 values (joints 1-7, {self.config.action_mode}), "
                f"got {a.size}"
            )
        if self.config.action_mode == "abs_pos":
            low, high = LOWER - LIMIT_TOLERANCE, UPPER + LIMIT_TOLERANCE
        else:
            high = UPPER - LOWER + LIMIT_TOLERANCE
            low = -high
        for i in range(7):
            if not (np.isfinite(a[i]) and low[i] <= a[i] <= high[i]):
                raise InvalidActionError(
                    f"action[{i}] ({JOINT_NAMES[i]}, {self.config.action_mode}) = {a[i]!r} "
                    f"is outside [{low[i] + LIMIT_TOLERANCE:.6f}, "
                    f"{high[i] - LIMIT_TOLERANCE:.6f}] rad"
                )
        return a

    def publish(self, command: np.ndarray | None) -> None:
        # None (no new command this tick): the position controller keeps its last target.
        if command is None or command is self._last_command:
            return
        # The handler republishes the same array during one action: a delta becomes a target
        # once per action, as the bridge computes it when the action arrives.
        self._last_command = command
        target = np.asarray(command, dtype=np.float64)
        if self.config.action_mode == "delta_pos":
            target = target + self._controller.position
        self._controller.command(target)

    def advance(self, dt: float) -> None:
        if not dt > 0:
            raise ValueError(f"advance needs dt > 0 s, got {dt!r}")
        self.time += dt
        moved = self._controller.step(dt)
        self._update_objects()
        if moved:
            self._sync_joints()
            if not self.in_collision:  # latched: nothing to learn until SetState
                self._check_collision()

    # -- objects and contacts -------------------------------------------------------------------
    def _update_objects(self, force: bool = False) -> None:
        t = self.time - self._object_start
        for i, trajectory in enumerate(self._objects):
            idx = trajectory.index(t)
            if idx != self._object_index[i] or force:
                self._object_index[i] = idx
                xyz = trajectory.samples[idx].tolist()
                self._world.client.resetBasePositionAndOrientation(
                    self._object_uids[i], xyz, _IDENTITY
                )

    def _check_collision(self) -> None:
        client = self._world.client
        client.performCollisionDetection()
        for contact in client.getContactPoints(bodyA=self._uid):
            if contact[8] > 0.0:  # PyBullet also lists near misses
                continue
            if (contact[1] == self._uid and contact[3] in self._sensor_links) or (
                contact[2] == self._uid and contact[4] in self._sensor_links
            ):
                self.in_collision = True
                return

    # -- state ----------------------------------------------------------------------------------
    def set_state(self, request: StateRequest) -> None:
        goal = self._joint_goal(request)
        rng = copy.deepcopy(self._rng)
        trajectories = [
            build_trajectory(i, request.string_params, request.float_params, rng)
            for i in range(len(self._objects))
        ]
        # Everything is validated: from here on nothing can fail.
        self._rng = rng
        self._controller.reset(goal)
        self._last_command = None
        self._sync_joints()
        for i, trajectory in enumerate(trajectories):
            if trajectory is not None:
                self._objects[i] = trajectory
        self._object_start = self.time
        self._update_objects(force=True)
        self.in_collision = False
        self._check_collision()

    def _joint_goal(self, request: StateRequest) -> np.ndarray:
        unknown = [k for k in request.state_dict if k not in ALL_KEYS]
        if unknown:
            raise InvalidStateError(
                f"unknown Panda state_dict keys {preview(unknown)}; known: {len(ALL_KEYS)} keys "
                f"such as {POSITION_KEYS[0]!r}"
            )
        missing = [k for k in POSITION_KEYS if k not in request.state_dict]
        if missing:
            raise InvalidStateError(
                f"Panda SetState needs the joint goal: state_dict lacks {missing}"
            )
        goal = np.array([float(request.state_dict[k]) for k in POSITION_KEYS])
        for i, key in enumerate(POSITION_KEYS):
            low, high = LOWER[i] - LIMIT_TOLERANCE, UPPER[i] + LIMIT_TOLERANCE
            if not (np.isfinite(goal[i]) and low <= goal[i] <= high):
                raise InvalidStateError(
                    f"joint goal {key} ({JOINT_NAMES[i]}) = {goal[i]!r} is outside "
                    f"[{LOWER[i]:.4f}, {UPPER[i]:.4f}] rad"
                )
        return goal

    def read_sensors(self, groups: Iterable[str] | None = None) -> dict[str, np.ndarray]:
        wanted = self.groups if groups is None else tuple(groups)
        out: dict[str, np.ndarray] = {}
        c = self._controller
        if "joints" in wanted:
            out["joints"] = np.concatenate([c.position, c.velocity, np.zeros(7)])
        if "ee" in wanted:
            state = self._world.client.getLinkState(
                self._uid, self._ee_link, computeForwardKinematics=1
            )
            out["ee"] = np.array([*state[4], *state[5]], dtype=np.float64)
        if "collision" in wanted:
            out["collision"] = np.array([1.0 if self.in_collision else 0.0])
        t = self.time - self._object_start
        for i, trajectory in enumerate(self._objects):
            if f"object_{i}" in wanted:
                out[f"object_{i}"] = np.concatenate([trajectory.position(t), _IDENTITY])
        return out

    def compose(self, groups: Mapping[str, np.ndarray]) -> StateSnapshot:
        return compose_state(self.config.rs_mode, groups)

    @property
    def joint_positions(self) -> np.ndarray:
        """Current joint positions (rad), a copy."""
        return self._controller.position.copy()

    def close(self) -> None:
        self._world.close()
