"""Simulated MiR100 mobile base, wire-compatible with robo-gym's ``mir100_robot_server``.

Action (SendAction ``[v, omega]``): the twist set-point for the next actuation tick.

=====  ==================  =====  =================================================
index  meaning             unit   accepted
=====  ==================  =====  =================================================
0      linear velocity v   m/s    any finite value; the controller clips to +-1.0
1      angular velocity w  rad/s  any finite value; the controller clips to +-1.5
=====  ==================  =====  =================================================

robo-gym's bridge does not clip actions (the ROS diff-drive controller does), so out-of-range
values are accepted and clipped here too; wrong length, NaN and inf are refused.

State: the 1030 values of spec c.1, see ``state``. SetState takes the target, teleports
the base (zero twist) and, in ``lab_6x8``, the three cubes.

Model (differences from Gazebo, all deliberate, for speed and determinism):

* The base is **kinematic**: the twist follows the set-point within the acceleration limits and
  the pose follows the twist (``drive``); the base body is teleported every substep.
* Contacts are checked after every substep with PyBullet's closest-point query. A substep that
  would bring the base into (deeper) contact is undone and the twist zeroed: the robot stops at
  the obstacle instead of pushing it. **Cubes are never pushed** (in Gazebo they can be).
* Nothing is physics-stepped, nothing sleeps; sim time advances only through ``advance(dt)``.
* Lasers: 1,012 retained beams in one ray batch (``lasers``), clean unless
  ``laser_noise_sigma`` > 0 (Gazebo uses 0.01 m).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping

import numpy as np

from robogym_ray.errors import InvalidActionError
from robogym_ray.robots.base import SimRobot, StateRequest, StateSnapshot
from robogym_ray.robots.mir100.card import CARD
from robogym_ray.robots.mir100.config import Mir100Config, parse_options
from robogym_ray.robots.mir100.drive import BaseState, clip, integrate, wrap_angle
from robogym_ray.robots.mir100.lasers import BACK, FRONT, BoxCaster, BulletCaster, Caster, LaserPair
from robogym_ray.robots.mir100.scenes import (
    CUBE_SIZE,
    OBSTACLES,
    TARGET_MARKER_Z,
    build_scene,
)
from robogym_ray.robots.mir100.state import GROUPS, compose_state, parse_set_state
from robogym_ray.robots.sim import PyBulletWorld

FOOTPRINT: tuple[float, float, float] = CARD.geometry.footprint  # type: ignore[assignment]
"""Base collision box (x, y, z size in m), as the URDF's base box (the card's footprint)."""
FOOTPRINT_OFFSET = (0.037646, 0.0, 0.20)
"""Box centre relative to the pose point (drive-axle centre on the floor), robot frame (m)."""
# The base belongs to no group the rays or the broadphase look at (mask 0), so the scanners,
# whose origins lie inside the box, never see the robot itself. Explicit closest-point queries
# ignore these filters, so contact checks still work.
_BASE_FILTER_GROUP = 0x4
_BASE_FILTER_MASK = 0x0


class Mir100Robot(SimRobot):
    """A MiR100 in its own PyBullet world (DIRECT), stepped by the robot server.

    Args:
        config: the robot's configuration.
        seed: seeds the laser noise; the model has no other randomness.
    """

    name = "mir100"

    def __init__(self, config: Mir100Config | None = None, seed: int | None = None) -> None:
        self.config = config or Mir100Config()
        self.handler_config = self.config.handler_config()
        self._limits = self.config.limits
        self.sensor_periods = {"f_scan": self.config.scan_period, "b_scan": self.config.scan_period}
        self.world = PyBulletWorld()
        self._collidable = {self.world.body(n) for n in build_scene(self.world, self.config.scene)}
        self._obstacles = OBSTACLES if self.config.scene == "lab_6x8" else ()
        self._base_uid = self._add_base()
        self._lasers = LaserPair(
            self._make_caster(),
            self.config.laser_range_min,
            self.config.laser_range_max,
            self.config.laser_noise_sigma,
            np.random.default_rng(seed),
        )
        self.sim_time = 0.0
        """Seconds of simulated time advanced so far."""
        self._target = (0.0, 0.0, 0.0)
        self._setpoint = (0.0, 0.0)
        self._collided = False
        self._version = 0  # bumped whenever the scene changes; keys the scan cache
        self._scan_cache: tuple[int, np.ndarray, np.ndarray] | None = None
        x, y, yaw = self.config.initial_pose
        self._reset_base(BaseState(x, y, wrap_angle(yaw)))

    def _make_caster(self) -> Caster:
        if self.config.laser_caster == "bullet":
            return BulletCaster(self.world.client)
        heights = (FRONT.z, BACK.z)
        return BoxCaster(self.world.client, sorted(self._collidable), heights)

    def _add_base(self) -> int:
        half = [s / 2 for s in FOOTPRINT]
        uid = self.world.add_box("mir", half, FOOTPRINT_OFFSET, rgba=(0.3, 0.3, 0.3, 1.0))
        self.world.client.setCollisionFilterGroupMask(
            uid, -1, _BASE_FILTER_GROUP, _BASE_FILTER_MASK
        )
        return uid

    # -- SimRobot interface -------------------------------------------------------------------
    def validate_action(self, action: np.ndarray) -> np.ndarray:
        values = np.asarray(action, dtype=np.float64).ravel()
        if len(values) != 2:
            raise InvalidActionError(
                f"MiR100 action has {len(values)} values; expected 2 ([v m/s, omega rad/s])"
            )
        limits = (self._limits.max_linear_velocity, self._limits.max_angular_velocity)
        for index, (value, limit) in enumerate(zip(values, limits, strict=True)):
            if not math.isfinite(value):
                raise InvalidActionError(
                    f"action[{index}] = {value}; expected a finite number "
                    f"(the controller clips it to [-{limit}, {limit}])"
                )
        return values

    def obstacle_poses(self) -> np.ndarray:
        """(x, y, yaw) of each cube where it stands now, shape (n cubes, 3); (0, 3) without."""
        poses = [self.world.pose(name) for name in self._obstacles]
        return np.array([[pos[0], pos[1], yaw] for pos, yaw in poses]).reshape(-1, 3)

    def set_state(self, request: StateRequest) -> None:
        # Parse (and so validate) everything before the first change to the world.
        parsed = parse_set_state(request.state, self.config.max_abs_position)
        self._target = parsed.target
        tx, ty, tyaw = parsed.target
        self.world.set_pose("target", (tx, ty, TARGET_MARKER_Z), tyaw)
        # Obstacle slots are ignored in scenes without cubes, as the ROS server's failing
        # teleport calls are.
        for name, (x, y, yaw) in zip(self._obstacles, parsed.obstacles, strict=False):
            self.world.set_pose(name, (x, y, CUBE_SIZE / 2), yaw)
        x, y, yaw = parsed.pose
        self._reset_base(BaseState(x, y, wrap_angle(yaw)))

    def publish(self, command: np.ndarray | None) -> None:
        if command is None:
            self._setpoint = (0.0, 0.0)
            return
        limits = self._limits
        self._setpoint = (
            clip(float(command[0]), limits.max_linear_velocity),
            clip(float(command[1]), limits.max_angular_velocity),
        )

    def advance(self, dt: float) -> None:
        if not (math.isfinite(dt) and dt >= 0):
            raise ValueError(f"advance(dt={dt}); expected a finite dt >= 0")
        # The flag reports contact during the latest tick only (the bumper is not latched).
        self._collided = False
        steps = max(1, math.ceil(dt / self.config.substep - 1e-9))
        h = dt / steps
        for _ in range(steps):
            self._substep(h)
        self.sim_time += dt
        self._version += 1

    def read_sensors(self, groups: Iterable[str] | None = None) -> dict[str, np.ndarray]:
        wanted = list(GROUPS) if groups is None else list(groups)
        unknown = [g for g in wanted if g not in GROUPS]
        if unknown:
            raise KeyError(f"unknown MiR100 sensor groups {unknown}; known: {list(GROUPS)}")
        base = self._base
        values: dict[str, np.ndarray] = {
            "target": np.array(self._target),
            "pose": np.array([base.x, base.y, base.yaw]),
            "twist": np.array([base.v, base.w]),
            "collision": np.array([1.0 if self._collided else 0.0]),
        }
        out = {g: values[g] for g in wanted if g in values}
        if "f_scan" in wanted or "b_scan" in wanted:
            front, back = self._scans()
            if "f_scan" in wanted:
                out["f_scan"] = front.copy()
            if "b_scan" in wanted:
                out["b_scan"] = back.copy()
        return out

    def compose(self, groups: Mapping[str, np.ndarray]) -> StateSnapshot:
        return StateSnapshot(state=compose_state(groups))

    def close(self) -> None:
        self.world.close()

    # -- internals ----------------------------------------------------------------------------
    @property
    def base(self) -> BaseState:
        """A copy of the current pose and twist."""
        return self._base.copy()

    def _reset_base(self, state: BaseState) -> None:
        """Teleport with zero twist and set-point; clears the collision flag."""
        self._base = state
        self._setpoint = (0.0, 0.0)
        self._place(state)
        self._clearance = self._measure_clearance()
        self._collided = False
        self._version += 1

    def _substep(self, h: float) -> None:
        current = self._base
        nxt = integrate(current, *self._setpoint, h, self._limits)
        if (nxt.x, nxt.y, nxt.yaw) == (current.x, current.y, current.yaw):
            # Standing still: no need to move the body; a standing contact still counts.
            self._base = nxt
            self._collided |= self._clearance <= 0.0
            return
        self._place(nxt)
        clearance = self._measure_clearance()
        if clearance <= 0.0:
            self._collided = True
            if clearance < self._clearance:
                # Into (deeper) contact: the obstacle stops the base. Undo the substep.
                self._place(current)
                current.v = current.w = 0.0
                return
        self._base = nxt
        self._clearance = clearance

    def _place(self, state: BaseState) -> None:
        c, s = math.cos(state.yaw), math.sin(state.yaw)
        ox, oy, oz = FOOTPRINT_OFFSET
        position = (state.x + c * ox - s * oy, state.y + s * ox + c * oy, oz)
        quat = (0.0, 0.0, math.sin(state.yaw / 2), math.cos(state.yaw / 2))
        self.world.client.resetBasePositionAndOrientation(self._base_uid, position, quat)

    def _measure_clearance(self) -> float:
        """Signed distance to the nearest touching collidable body (<= 0), or inf if none."""
        if not self._collidable:
            return math.inf
        client = self.world.client
        # Broadphase first: only bodies whose boxes overlap the base's need an exact query.
        lo, hi = client.getAABB(self._base_uid)
        nearest = math.inf
        for uid, _ in client.getOverlappingObjects(lo, hi) or ():
            if uid in self._collidable:
                for point in client.getClosestPoints(self._base_uid, uid, 0.0):
                    nearest = min(nearest, point[8])
        return nearest

    def _scans(self) -> tuple[np.ndarray, np.ndarray]:
        # Cached per scene version, so reading twice between ticks gives the same (noisy) scan.
        if self._scan_cache is None or self._scan_cache[0] != self._version:
            b = self._base
            front, back = self._lasers.scan(b.x, b.y, b.yaw)
            self._scan_cache = (self._version, front, back)
        return self._scan_cache[1], self._scan_cache[2]


__all__ = ["FOOTPRINT", "FOOTPRINT_OFFSET", "Mir100Config", "Mir100Robot", "make_mir100"]


def make_mir100(
    model: str, scene: str | None, seed: int | None, options: Mapping[str, str]
) -> Mir100Robot:
    """Registry factory: a MiR100 from robo-gym launch arguments (see ``parse_options``).

    Args:
        seed: seeds the laser noise.
    """
    return Mir100Robot(parse_options(model, scene, options), seed=seed)
