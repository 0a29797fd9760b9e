"""The simulated Franka Emika Panda behind robo-gym-robot-servers 2.1.0's Panda contract, and
the Franka Research 3 (``fr3``) behind the same contract with its own joint limits.

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

from collections.abc import Mapping, Sequence

import numpy as np

from robogym_ray.robots.arm import SimArm
from robogym_ray.robots.base import StateRequest, StateSnapshot
from robogym_ray.robots.command_handler import CommandHandlerConfig
from robogym_ray.robots.panda.checks import check_joint_action, check_joint_goal
from robogym_ray.robots.panda.config import PandaConfig, parse_options
from robogym_ray.robots.panda.controller import JointPositionController
from robogym_ray.robots.panda.model import JOINT_NAMES, LINK_NAMES, urdf_path
from robogym_ray.robots.panda.state import (
    N_OBJECTS,
    compose_state,
    sensor_groups,
)
from robogym_ray.robots.scenes import SCENES, add_scene


def make_panda(
    model: str, scene: str | None, seed: int | None, options: Mapping[str, str]
) -> PandaArm:
    """Registry factory: a simulated Panda or FR3 (``model``) configured by launch-style
    ``options``."""
    return PandaArm(parse_options(model, scene, options), seed=seed)


class PandaArm(SimArm):
    """One Franka arm (arm, hand, open fingers) and its scene in a PyBullet DIRECT world: the
    Panda, or the FR3 (``config.model``), which differs in its joint limits only."""

    def __init__(self, config: PandaConfig, seed: int | None = None) -> None:
        self.config = config
        self.name = config.model
        self.limits = config.limits
        self.handler_config = CommandHandlerConfig(
            action_cycle=config.action_cycle, actuation_cycle=config.actuation_cycle
        )
        self.sensor_periods = {}
        self.groups = sensor_groups(config.rs_mode)
        lower, upper = self.limits.lower, self.limits.upper
        controller = JointPositionController(
            config.max_velocity_scale_factor * self.limits.velocity, lower, upper
        )
        controller.reset(np.clip(np.zeros(7), lower, upper))
        super().__init__(controller, N_OBJECTS[config.rs_mode], seed)

    # -- scene ----------------------------------------------------------------------------------
    def _build_scene(self) -> None:
        scene = SCENES[self.config.scene]
        add_scene(self._world, scene)
        index = self._load_robot(urdf_path(self.config.model), (0.0, 0.0, 0.0))
        self._joint_ids = [index[n] for n in JOINT_NAMES]
        # Contact sensors: links 1-7 and the hand with its fingers (shapes of panda_link8).
        self._contact_links = frozenset(index[n] for n in (*LINK_NAMES, "panda_link8"))
        self._ee_link = index[self.config.ee_frame]
        self._add_objects(N_OBJECTS[self.config.rs_mode], collision=scene.object_collision)

    # -- actions --------------------------------------------------------------------------------
    def validate_action(self, action: np.ndarray) -> np.ndarray:
        lower, upper = self.limits.lower, self.limits.upper
        return check_joint_action(action, self.config.action_mode, lower, upper, self.config.label)

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

    # -- state ----------------------------------------------------------------------------------
    def _joint_goal(self, request: StateRequest) -> np.ndarray:
        """The validated joint goal (joints 1-7) of a SetState: all seven keys, within limits."""
        return check_joint_goal(request, self.limits.lower, self.limits.upper, self.config.label)

    def _arm_sensors(self, wanted: Sequence[str]) -> dict[str, np.ndarray]:
        out: dict[str, np.ndarray] = {}
        c = self._controller
        if "joints" in wanted:
            # No dynamics, so no efforts: robo-gym's layout still carries seven (as 0).
            out["joints"] = np.concatenate([c.position, c.velocity, np.zeros(7)])
        if "ee" in wanted:
            self._sync_joints()
            state = self._world.client.getLinkState(
                self._uid, self._ee_link, computeForwardKinematics=1
            )
            out["ee"] = np.array([*state[4], *state[5]], dtype=np.float64)
        return out

    def compose(self, groups: Mapping[str, np.ndarray]) -> StateSnapshot:
        return compose_state(self.config.rs_mode, groups)
