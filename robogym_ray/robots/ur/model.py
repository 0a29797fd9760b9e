"""Simulated Universal Robots arms (ur3 ... ur16e) behind robo-gym's UR robot-server contract.

========================  ==================================================================
wire                      meaning
========================  ==================================================================
SendAction                6 floats, ROS order [elbow, shoulder_lift, shoulder_pan, wrist_1,
                          wrist_2, wrist_3]: absolute targets (abs_pos, servo_pos) or deltas
                          (delta_pos), |value| <= the joint's position limit (+1e-4 for
                          float32 rounding)
SetState ``state_dict``   the six ``*_joint_position`` goals (else ``state[6:12]``, ROS order);
                          every other known key is ignored, unknown keys are an error
SetState params           ``object_<i>_function`` + ``object_<i>_*`` floats (``objects``);
                          servo_pos: ``servo_<name>_<j>`` floats, the servo's gains and
                          friction for the episode (``servo.servo_params``)
GetState                  the rs_mode's exact key set + flat list (``state``); ``ee_to_ref_*``
                          is the launch argument ``ee_frame`` (tool0, or tool1 = tool0 turned
                          by IsaacLab's fixed rotation, ``geometry.TOOL1_RPY``)
========================  ==================================================================

Differences from the ROS/Gazebo server, all deliberate (sim time is free, Gazebo is not here):

* The controller is kinematic (``controller``): positions follow the trajectory exactly, joint
  velocities are its derivative, targets beyond a joint limit are clipped to the limit.
  ``action_mode:=servo_pos`` (ours) tracks streamed targets with a PD servo instead
  (``servo``), ticked at Isaac Lab's 120 Hz physics step.
* SetState *places* the arm at the goal (velocity 0) instead of driving it there; the result is
  the same state the ROS server waits for, without the 0.03 rad residual. Objects restart at their
  first sample when SetState returns (ROS lets them run for 20 control periods first).
* Collisions: PyBullet contacts of the six moving links (against the ground, the table, a
  colliding object sphere, or non-adjacent links of the arm) after every actuation tick in which
  something moved, latched until the next SetState, like the Gazebo contact sensors.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import numpy as np

from robogym_ray.errors import InvalidActionError, InvalidStateError
from robogym_ray.robots.arm import LIMIT_TOLERANCE, SimArm, check_state_keys
from robogym_ray.robots.base import StateRequest, StateSnapshot
from robogym_ray.robots.command_handler import CommandHandlerConfig
from robogym_ray.robots.scenes import SCENES, add_scene
from robogym_ray.robots.ur.config import URConfig, parse_options
from robogym_ray.robots.ur.controller import JointTrajectoryController
from robogym_ray.robots.ur.geometry import (
    JOINT_NAMES,
    LINK_NAMES,
    POSITION_LIMITS,
    ROS_FROM_ENV,
    UR_MODELS,
    urdf_path,
)
from robogym_ray.robots.ur.servo import PHYSICS_DT, JointServo, nominal_params, servo_params
from robogym_ray.robots.ur.state import (
    ALL_KEYS,
    N_OBJECTS,
    POSITION_KEYS,
    compose_state,
    sensor_groups,
)

ROS_JOINT_NAMES = tuple(JOINT_NAMES[i] for i in ROS_FROM_ENV)
_ROT_Z_PI = np.array([-1.0, -1.0, 1.0])


def make_ur(model: str, scene: str | None, seed: int | None, options: Mapping[str, str]) -> URArm:
    """Registry factory: a simulated ``model`` arm configured by launch-style ``options``."""
    return URArm(parse_options(model, scene, options), seed=seed)


class URArm(SimArm):
    """One UR arm with its scene and objects in a PyBullet DIRECT world, stepped in sim time."""

    def __init__(self, config: URConfig, seed: int | None = None) -> None:
        self.config = config
        self.model = UR_MODELS[config.model]
        self.name = config.model
        self.servo = config.action_mode == "servo_pos"
        actuation = config.actuation_cycle
        if self.servo:  # one tick per physics step: each action cycle in whole steps of <= 1/120 s
            actuation = config.action_cycle / math.ceil(config.action_cycle / PHYSICS_DT - 1e-9)
        self.handler_config = CommandHandlerConfig(
            action_cycle=config.action_cycle, actuation_cycle=actuation, repeat=config.repeat
        )
        self.sensor_periods = {}
        self.groups = sensor_groups(config.rs_mode)
        self._target = np.zeros(6)
        vmax = config.max_velocity_scale_factor * np.asarray(self.model.max_velocity)
        kind = JointServo if self.servo else JointTrajectoryController
        super().__init__(kind(vmax, POSITION_LIMITS), N_OBJECTS[config.rs_mode], seed)

    # -- scene ----------------------------------------------------------------------------------
    def _build_scene(self) -> None:
        scene = SCENES[self.config.scene]
        add_scene(self._world, scene)
        index = self._load_robot(urdf_path(self.model), (0.0, 0.0, self.config.base_height))
        self._joint_ids = [index[n] for n in JOINT_NAMES]
        self._contact_links = frozenset(index[n] for n in LINK_NAMES)
        # tool1 is a fixed child of tool0 in our URDF, as in the ROS server's tf tree.
        self._frame_ids = [index[self.config.ee_frame], index["forearm_link"]]
        self._add_objects(N_OBJECTS[self.config.rs_mode], collision=scene.object_collision)

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

    # -- objects and frames ---------------------------------------------------------------------
    def _object_to_world(self, xyz: np.ndarray) -> np.ndarray:
        base_link = xyz * _ROT_Z_PI if self.config.reference_frame == "base" else xyz
        return base_link + np.array([0.0, 0.0, self.config.base_height])

    # -- state ----------------------------------------------------------------------------------
    def set_state(self, request: StateRequest) -> None:
        params = servo_params(request.float_params)  # validated before anything changes
        if params is not None and not self.servo:
            raise InvalidStateError(
                f"SetState servo_* params need action_mode servo_pos; this arm runs "
                f"{self.config.action_mode} (robo-gym's trajectories have no gains)"
            )
        super().set_state(request)
        if self.servo:  # each SetState starts an episode: absent params mean nominal gains
            controller: JointServo = self._controller  # type: ignore[assignment]
            controller.set_gains(**(params or nominal_params()))

    def _joint_goal(self, request: StateRequest) -> np.ndarray:
        """The validated joint goal (env order) of a SetState."""
        check_state_keys("UR", request.state_dict, ALL_KEYS, POSITION_KEYS[0])
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

    def _arm_sensors(self, wanted: Sequence[str]) -> dict[str, np.ndarray]:
        out: dict[str, np.ndarray] = {}
        if "joints" in wanted:
            out["joints"] = np.concatenate([self._controller.position, self._controller.velocity])
        if "ee" in wanted or "forearm" in wanted:
            self._sync_joints()
            states = self._link_states(self._uid, self._frame_ids, computeForwardKinematics=1)
            for name, state in zip(("ee", "forearm"), states, strict=True):
                if name in wanted:
                    out[name] = self._pose_in_ref(state[4], state[5])
        return out

    def _pose_in_ref(self, world_xyz, quat_xyzw) -> np.ndarray:
        x, y, z = world_xyz
        qx, qy, qz, qw = quat_xyzw
        z -= self.config.base_height
        if self.config.reference_frame == "base":
            # Rz(pi) (x) q: positions (-x, -y, z), quaternion (-qy, qx, qw, -qz).
            return np.array([-x, -y, z, -qy, qx, qw, -qz])
        return np.array([x, y, z, qx, qy, qz, qw])

    def compose(self, groups: Mapping[str, np.ndarray]) -> StateSnapshot:
        return compose_state(self.config.rs_mode, groups)
