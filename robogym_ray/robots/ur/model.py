"""Simulated Universal Robots arms (ur3 ... ur16e) behind robo-gym's UR robot-server contract.

========================  ==================================================================
wire                      meaning
========================  ==================================================================
SendAction                6 floats, ROS order [elbow, shoulder_lift, shoulder_pan, wrist_1,
                          wrist_2, wrist_3]: absolute targets (abs_pos) or deltas (delta_pos),
                          |value| <= the joint's position limit (+1e-4 for float32 rounding)
SetState ``state_dict``   the six ``*_joint_position`` goals (else ``state[6:12]``, ROS order);
                          every other known key is ignored, unknown keys are an error
SetState params           ``object_<i>_function`` + ``object_<i>_*`` floats (``objects``)
GetState                  the rs_mode's exact key set + flat list (``state``)
========================  ==================================================================

Differences from the ROS/Gazebo server, all deliberate (sim time is free, Gazebo is not here):

* The controller is kinematic (``controller``): positions follow the trajectory exactly, joint
  velocities are its derivative, targets beyond a joint limit are clipped to the limit.
* SetState *places* the arm at the goal (velocity 0) instead of driving it there; the result is
  the same state the ROS server waits for, without the 0.03 rad residual. Objects restart at their
  first sample when SetState returns (ROS lets them run for 20 control periods first).
* Collisions: PyBullet contacts of the six moving links (against the ground, the table, a
  colliding object sphere, or non-adjacent links of the arm) after every actuation tick in which
  something moved, latched until the next SetState, like the Gazebo contact sensors.
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
from robogym_ray.robots.sim import PyBulletWorld
from robogym_ray.robots.ur.config import SCENES, URConfig, parse_options
from robogym_ray.robots.ur.controller import JointTrajectoryController
from robogym_ray.robots.ur.geometry import (
    BASE_LINK_HEIGHT,
    JOINT_NAMES,
    LINK_NAMES,
    POSITION_LIMITS,
    ROS_FROM_ENV,
    UR_MODELS,
    urdf_path,
)
from robogym_ray.robots.ur.state import (
    ALL_KEYS,
    N_OBJECTS,
    POSITION_KEYS,
    compose_state,
    sensor_groups,
)
from robogym_ray.robots.validation import preview

ROS_JOINT_NAMES = tuple(JOINT_NAMES[i] for i in ROS_FROM_ENV)
LIMIT_TOLERANCE = 1e-4
"""Slack on position limits: float32 on the wire rounds 2*pi and pi up by ~1e-7."""
OBJECT_RADIUS = 0.025
CONTACT_DISTANCE = 0.0
"""Contacts count when the signed distance is <= this (m); PyBullet also reports near misses."""
_ROT_Z_PI = np.array([-1.0, -1.0, 1.0])


def make_ur(model: str, scene: str | None, seed: int | None, options: Mapping[str, str]) -> URArm:
    """Registry factory: a simulated ``model`` arm configured by launch-style ``options``."""
    return URArm(parse_options(model, scene, options), seed=seed)


class URArm(SimRobot):
    """One UR arm with its scene and objects in a PyBullet DIRECT world, stepped in sim time."""

    def __init__(self, config: URConfig, seed: int | None = None) -> None:
        self.config = config
        self.model = UR_MODELS[config.model]
        self.name = config.model
        self.handler_config = CommandHandlerConfig(
            action_cycle=config.action_cycle,
            actuation_cycle=config.actuation_cycle,
            repeat=config.repeat,
        )
        self.sensor_periods = {}
        self.groups = sensor_groups(config.rs_mode)
        self._rng = np.random.default_rng(seed)
        self._controller = JointTrajectoryController(
            config.max_velocity_scale_factor * np.asarray(self.model.max_velocity), POSITION_LIMITS
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
        self._target = np.zeros(6)
        self.in_collision = False
        self._update_objects()
        self._check_collision()

    # -- scene ----------------------------------------------------------------------------------
    def _build_scene(self) -> None:
        world, scene = self._world, SCENES[self.config.scene]
        world.add_plane("ground")
        if scene.table:
            world.add_box("table", (0.5, 0.5, 0.05), (-0.05, 0.2, 0.05))
        flags = p.URDF_USE_SELF_COLLISION | p.URDF_USE_SELF_COLLISION_EXCLUDE_PARENT
        self._uid = world.load_urdf(
            "robot", urdf_path(self.model), (0.0, 0.0, BASE_LINK_HEIGHT), flags=flags
        )
        index = {}
        for j in range(world.client.getNumJoints(self._uid)):
            info = world.client.getJointInfo(self._uid, j)
            index[info[1].decode()] = j
            index[info[12].decode()] = j  # child link index == joint index in PyBullet
        self._joint_ids = [index[n] for n in JOINT_NAMES]
        self._moving_links = frozenset(index[n] for n in LINK_NAMES)
        self._frame_ids = [index["tool0"], index["forearm_link"]]
        self._object_uids = [
            world.add_sphere(
                f"object_{i}", OBJECT_RADIUS, (float(i), 0.0, 3.0),
                collision=scene.object_collision,
            )
            for i in range(N_OBJECTS[self.config.rs_mode])
        ]  # fmt: skip
        self._colliding_objects = scene.object_collision
        self._bind_calls()
        self._joints_stale = True

    def _bind_calls(self) -> None:
        # BulletClient builds a functools.partial on every attribute access; the hot loop uses
        # these once-built ones instead (a measurable share of a 5-tick action).
        client = self._world.client
        self._reset_joints = client.resetJointStatesMultiDof
        self._reset_base = client.resetBasePositionAndOrientation
        self._detect = client.performCollisionDetection
        self._contacts = client.getContactPoints
        self._link_states = client.getLinkStates

    def _sync_joints(self) -> None:
        """Copy the controller's positions into PyBullet, lazily (only contacts and frames read
        them, and a latched collision flag makes per-tick contact queries pointless)."""
        if self._joints_stale:
            q = self._controller.position.reshape(6, 1).tolist()
            self._reset_joints(self._uid, self._joint_ids, q)
            self._joints_stale = False

    # -- actions --------------------------------------------------------------------------------
    def validate_action(self, action: np.ndarray) -> np.ndarray:
        a = np.asarray(action, dtype=np.float64).reshape(-1)
        if a.shape != (6,):
            raise InvalidActionError(
                f"UR action must have 6 values (ROS order {list(ROS_JOINT_NAMES)}), got {a.size}"
            )
        limits = POSITION_LIMITS[list(ROS_FROM_ENV)]
        for i in range(6):
            if not np.isfinite(a[i]) or abs(a[i]) > limits[i] + LIMIT_TOLERANCE:
                raise InvalidActionError(
                    f"action[{i}] ({ROS_JOINT_NAMES[i]}, {self.config.action_mode}) = {a[i]!r} "
                    f"is outside [{-limits[i]:.6f}, {limits[i]:.6f}] rad"
                )
        return a

    def publish(self, command: np.ndarray | None) -> None:
        if command is None:
            self._last_command = None
            self._controller.stop()
            return
        # The handler republishes the *same array* for one action's ticks, so identity tells a
        # repeat from a new action: a delta is turned into a target once per action, as the ROS
        # server does when the action arrives.
        if command is not self._last_command:
            self._last_command = command
            env = np.asarray(command, dtype=np.float64)[list(ROS_FROM_ENV)]
            if self.config.action_mode == "delta_pos":
                env = env + self._controller.position
            self._target = self._controller.clip(env)
        self._controller.command(self._target, clipped=True)

    def advance(self, dt: float) -> None:
        if not dt > 0:
            raise ValueError(f"advance needs dt > 0 s, got {dt!r}")
        self.time += dt
        moved = self._controller.step(dt)
        self._joints_stale = self._joints_stale or moved
        moved = self._update_objects() or moved
        # A latched flag cannot change until SetState, so skip the (dominant) contact query.
        if moved and not self.in_collision:
            self._check_collision()

    # -- objects and contacts -------------------------------------------------------------------
    def _update_objects(self, force: bool = False) -> bool:
        """Move objects to their current sample; returns whether a colliding object moved."""
        moved = False
        t = self.time - self._object_start
        for i, trajectory in enumerate(self._objects):
            idx = trajectory.index(t)
            if idx == self._object_index[i] and not force:
                continue
            self._object_index[i] = idx
            xyz = self._ref_to_world(trajectory.samples[idx])
            self._reset_base(self._object_uids[i], xyz.tolist(), (0.0, 0.0, 0.0, 1.0))
            moved = moved or self._colliding_objects
        return moved

    def _check_collision(self) -> None:
        self._sync_joints()
        self._detect()
        for contact in self._contacts(bodyA=self._uid):
            if contact[8] > CONTACT_DISTANCE:
                continue
            ours_a = contact[1] == self._uid and contact[3] in self._moving_links
            ours_b = contact[2] == self._uid and contact[4] in self._moving_links
            if ours_a or ours_b:
                self.in_collision = True
                return

    def _ref_to_world(self, xyz: np.ndarray) -> np.ndarray:
        base_link = xyz * _ROT_Z_PI if self.config.reference_frame == "base" else xyz
        return base_link + np.array([0.0, 0.0, BASE_LINK_HEIGHT])

    # -- state ----------------------------------------------------------------------------------
    def set_state(self, request: StateRequest) -> None:
        goal = self._joint_goal(request)
        trajectories, rng = self._object_trajectories(request)
        # Everything is validated: from here on nothing can fail.
        self._rng = rng
        self._controller.reset(goal)
        self._last_command = None
        self._joints_stale = True
        for i, trajectory in enumerate(trajectories):
            if trajectory is not None:
                self._objects[i] = trajectory
        self._object_start = self.time
        self._update_objects(force=True)
        self.in_collision = False
        self._check_collision()

    def _joint_goal(self, request: StateRequest) -> np.ndarray:
        """The validated joint goal (env order) of a SetState."""
        unknown = [k for k in request.state_dict if k not in ALL_KEYS]
        if unknown:
            # Quoted in part: the message goes into the reply and the log (see validation).
            raise InvalidStateError(
                f"unknown UR state_dict keys {preview(unknown)}; known: {len(ALL_KEYS)} keys "
                f"such as {POSITION_KEYS[0]!r}"
            )
        missing = [k for k in POSITION_KEYS if k not in request.state_dict]
        if not missing:
            goal = np.array([float(request.state_dict[k]) for k in POSITION_KEYS])
            names = list(POSITION_KEYS)
        elif len(request.state) >= 12:  # the ROS server's fallback: state[6:12], ROS order
            goal = np.asarray(request.state[6:12], dtype=np.float64)[list(ROS_FROM_ENV)]
            names = [f"state[{6 + ROS_FROM_ENV[i]}]" for i in range(6)]
        else:
            raise InvalidStateError(
                f"SetState needs the joint goal: state_dict lacks {missing} and the flat state "
                f"has {len(request.state)} values (needs >= 12)"
            )
        for i in range(6):
            limit = POSITION_LIMITS[i]
            if not np.isfinite(goal[i]) or abs(goal[i]) > limit + LIMIT_TOLERANCE:
                raise InvalidStateError(
                    f"joint goal {names[i]} ({JOINT_NAMES[i]}) = {goal[i]!r} is outside "
                    f"[{-limit:.6f}, {limit:.6f}] rad"
                )
        return goal

    def _object_trajectories(
        self, request: StateRequest
    ) -> tuple[list[ObjectTrajectory | None], np.random.Generator]:
        """Build the requested trajectories with a copy of the RNG, committed only on success."""
        rng = copy.deepcopy(self._rng)
        trajectories = [
            build_trajectory(i, request.string_params, request.float_params, rng)
            for i in range(len(self._objects))
        ]
        return trajectories, rng

    def read_sensors(self, groups: Iterable[str] | None = None) -> dict[str, np.ndarray]:
        wanted = self.groups if groups is None else tuple(groups)
        out: dict[str, np.ndarray] = {}
        if "joints" in wanted:
            out["joints"] = np.concatenate([self._controller.position, self._controller.velocity])
        if "ee" in wanted or "forearm" in wanted:
            self._sync_joints()
            states = self._link_states(self._uid, self._frame_ids, computeForwardKinematics=1)
            for name, state in zip(("ee", "forearm"), states, strict=True):
                if name in wanted:
                    out[name] = self._pose_in_ref(state[4], state[5])
        if "collision" in wanted:
            out["collision"] = np.array([1.0 if self.in_collision else 0.0])
        t = self.time - self._object_start
        for i, trajectory in enumerate(self._objects):
            if f"object_{i}" in wanted:
                out[f"object_{i}"] = np.concatenate([trajectory.position(t), [0.0, 0.0, 0.0, 1.0]])
        return out

    def _pose_in_ref(self, world_xyz, quat_xyzw) -> np.ndarray:
        x, y, z = world_xyz
        qx, qy, qz, qw = quat_xyzw
        z -= BASE_LINK_HEIGHT
        if self.config.reference_frame == "base":
            # Rz(pi) (x) q: positions (-x, -y, z), quaternion (-qy, qx, qw, -qz).
            return np.array([-x, -y, z, -qy, qx, qw, -qz])
        return np.array([x, y, z, qx, qy, qz, qw])

    def compose(self, groups: Mapping[str, np.ndarray]) -> StateSnapshot:
        return compose_state(self.config.rs_mode, groups)

    @property
    def joint_positions(self) -> np.ndarray:
        """Current joint positions (rad), env order (a copy)."""
        return self._controller.position.copy()

    def close(self) -> None:
        self._world.close()
