"""What robo-gym's simulated arms share: SetState, object trajectories and latched contacts.

The UR and Panda robot servers keep one contract on the arm side, and ``SimArm`` implements it
once:

* SetState validates the joint goal and the object trajectories before touching anything, then
  *places* the arm at the goal (velocity 0) and restarts the objects at their first sample;
* objects follow their sampled trajectories in sim time (``robots/objects.py``);
* contacts of the arm's sensor links (against the ground, a table, a colliding object or
  non-adjacent links) are checked after every tick in which something moved and latched until
  the next SetState, like the Gazebo contact sensors the ROS bridges listen to.

A robot subclass brings what differs in substance: its scene (``_build_scene``), its joint goal
(``_joint_goal``: key names, limits, fallbacks), its action handling (``validate_action``,
``publish``), its frame sensors (``_arm_sensors``) and its state layout (``compose``).
"""

from __future__ import annotations

import copy
from abc import abstractmethod
from collections.abc import Iterable, Mapping, Sequence
from typing import Protocol

import numpy as np
import pybullet as p

from robogym_ray.errors import InvalidStateError
from robogym_ray.robots.base import SimRobot, StateRequest
from robogym_ray.robots.objects import ObjectTrajectory, build_trajectory, parked
from robogym_ray.robots.sim import PyBulletWorld, Vec3
from robogym_ray.text import preview

LIMIT_TOLERANCE = 1e-4
"""Slack on position limits (rad): float32 on the wire rounds a limit such as 2*pi, pi or 2.8973
up by ~1e-7, and a goal read back from GetState must pass again."""
OBJECT_RADIUS = 0.025
"""robo-gym's object spheres (``sphere50``) have a 50 mm diameter."""
CONTACT_DISTANCE = 0.0
"""Contacts count when the signed distance is <= this (m); PyBullet also reports near misses."""
_IDENTITY = (0.0, 0.0, 0.0, 1.0)


class ArmController(Protocol):
    """The part of a joint controller ``SimArm`` drives; commands stay the robot's own."""

    position: np.ndarray
    velocity: np.ndarray

    def reset(self, position: np.ndarray) -> None:
        """Place the joints at ``position`` (clipped into the limits), at rest."""

    def step(self, dt: float) -> bool:
        """Advance ``dt`` seconds; return whether the joints moved."""


def check_state_keys(
    robot: str, state_dict: Mapping[str, float], known: Iterable[str], example: str
) -> None:
    """Refuse SetState keys that no rs_mode of ``robot`` knows.

    Raises:
        InvalidStateError: naming a bounded preview of the unknown keys (the message goes into
            the reply and the log, see ``validation``).
    """
    known = frozenset(known)
    unknown = [k for k in state_dict if k not in known]
    if unknown:
        raise InvalidStateError(
            f"unknown {robot} state_dict keys {preview(unknown)}; known: {len(known)} keys "
            f"such as {example!r}"
        )


class SimArm(SimRobot):
    """An arm, its scene and its objects in a PyBullet DIRECT world, stepped in sim time.

    Args:
        controller: the joint controller, already at its start position.
        n_objects: objects of the rs_mode (parked until a SetState gives them a trajectory).
        seed: seeds the RNG that samples object trajectories.
    """

    groups: tuple[str, ...]
    """The sensor groups of this robot's rs_mode."""

    def __init__(self, controller: ArmController, n_objects: int, seed: int | None) -> None:
        self._rng = np.random.default_rng(seed)
        self._controller = controller
        self._world = PyBulletWorld()
        self._uid = -1
        self._joint_ids: list[int] = []
        self._contact_links: frozenset[int] = frozenset()
        """Links whose contacts count as the robot's collisions."""
        self._object_uids: list[int] = []
        self._colliding_objects = False
        self._build_scene()
        self._bind_calls()
        self._joints_stale = True
        self.time = 0.0
        """Sim time (s), advanced only by ``advance``."""
        self._objects: list[ObjectTrajectory] = [parked(i) for i in range(n_objects)]
        self._object_start = 0.0
        self._object_index = [-1] * n_objects
        self._last_command: np.ndarray | None = None
        self.in_collision = False
        self._update_objects()
        self._check_collision()

    # -- what a robot brings --------------------------------------------------------------------
    @abstractmethod
    def _build_scene(self) -> None:
        """Add ground, table, robot and objects to ``self._world``; set ``_uid``, ``_joint_ids``,
        ``_contact_links``, ``_object_uids`` and ``_colliding_objects``."""

    @abstractmethod
    def _joint_goal(self, request: StateRequest) -> np.ndarray:
        """The validated joint goal of a SetState; InvalidStateError otherwise."""

    @abstractmethod
    def _arm_sensors(self, wanted: Sequence[str]) -> dict[str, np.ndarray]:
        """The ``joints`` group and the frame groups (``ee`` ...) among ``wanted``."""

    def _object_to_world(self, xyz: np.ndarray) -> np.ndarray:
        """An object sample (reference frame) in PyBullet's world frame; the same by default."""
        return xyz

    # -- scene helpers --------------------------------------------------------------------------
    def _load_robot(self, urdf: str, base_xyz: Vec3) -> dict[str, int]:
        """Load the arm with self-collision; return joint *and* child-link names -> index."""
        client = self._world.client
        flags = p.URDF_USE_SELF_COLLISION | p.URDF_USE_SELF_COLLISION_EXCLUDE_PARENT
        self._uid = self._world.load_urdf("robot", urdf, base_xyz, flags=flags)
        index = {}
        for j in range(client.getNumJoints(self._uid)):
            info = client.getJointInfo(self._uid, j)
            index[info[1].decode()] = j
            index[info[12].decode()] = j  # child link index == joint index in PyBullet
        return index

    def _add_objects(self, n_objects: int, collision: bool) -> None:
        """robo-gym's object spheres, parked apart high above the scene until SetState."""
        self._object_uids = [
            self._world.add_sphere(
                f"object_{i}", OBJECT_RADIUS, (float(i), 0.0, 3.0), collision=collision
            )
            for i in range(n_objects)
        ]
        self._colliding_objects = collision

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
            q = self._controller.position.reshape(-1, 1).tolist()
            self._reset_joints(self._uid, self._joint_ids, q)
            self._joints_stale = False

    # -- stepping -------------------------------------------------------------------------------
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

    def _update_objects(self, force: bool = False) -> bool:
        """Move objects to their current sample; returns whether a colliding object moved."""
        moved = False
        t = self.time - self._object_start
        for i, trajectory in enumerate(self._objects):
            idx = trajectory.index(t)
            if idx == self._object_index[i] and not force:
                continue
            self._object_index[i] = idx
            xyz = self._object_to_world(trajectory.samples[idx])
            self._reset_base(self._object_uids[i], xyz.tolist(), _IDENTITY)
            moved = moved or self._colliding_objects
        return moved

    def _check_collision(self) -> None:
        self._sync_joints()
        self._detect()
        for contact in self._contacts(bodyA=self._uid):
            if contact[8] > CONTACT_DISTANCE:
                continue
            ours_a = contact[1] == self._uid and contact[3] in self._contact_links
            ours_b = contact[2] == self._uid and contact[4] in self._contact_links
            if ours_a or ours_b:
                self.in_collision = True
                return

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
        out = self._arm_sensors(wanted)
        if "collision" in wanted:
            out["collision"] = np.array([1.0 if self.in_collision else 0.0])
        t = self.time - self._object_start
        for i, trajectory in enumerate(self._objects):
            if f"object_{i}" in wanted:
                out[f"object_{i}"] = np.concatenate([trajectory.position(t), _IDENTITY])
        return out

    @property
    def joint_positions(self) -> np.ndarray:
        """Current joint positions (rad), the robot's joint order (a copy)."""
        return self._controller.position.copy()

    def close(self) -> None:
        self._world.close()
