"""UR avoidance tasks (robo-gym HEAD contract, spec d.5 and d.6): keep a pose or follow a
reference trajectory while a moving sphere (object 0) passes by.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, ClassVar

import numpy as np

from robogym_ray.envs.base import StepInfo
from robogym_ray.envs.frames import box, frame_xyz, in_frame, spherical
from robogym_ray.envs.outcomes import COLLISION, SUCCESS
from robogym_ray.envs.ur_common import URTask, normalize_joints
from robogym_ray.protocol import robot_server_pb2 as pb
from robogym_ray.protocol.client import RobotServerClient

RAAD_START = (-1.234, -1.854, -1.781, -1.069, 1.595, 0.0)
RAAD_SEGMENTS = (162, 137, 213)


def raad_reference_trajectory() -> list[np.ndarray]:
    """Substitute for robo-gym's ``trajectory_raad_2022.json`` (not available offline).

    Three segments of 162, 137 and 213 waypoints (as the original), env order, rad. They join
    three via configurations ``V0 = RAAD_START`` (the original's first waypoint),
    ``V1 = V0 + [0.8, 0.2, -0.2, 0.15, 0, 0]`` and ``V2 = V0 + [1.6, 0, 0.25, -0.1, 0, 0]``
    (V0 -> V1 -> V2 -> V0, so the trajectory loops) with a minimum-jerk profile
    ``10 s^3 - 15 s^4 + 6 s^5``: smooth, at rest at every via point, at most ~0.01 rad between
    waypoints - the arm sweeps about 90 degrees around the base above the table and back.
    """
    v0 = np.array(RAAD_START)
    vias = [v0, v0 + [0.8, 0.2, -0.2, 0.15, 0, 0], v0 + [1.6, 0.0, 0.25, -0.1, 0, 0], v0]
    segments = []
    for k, n in enumerate(RAAD_SEGMENTS):
        s = np.linspace(0.0, 1.0, n)[:, None]
        blend = 10 * s**3 - 15 * s**4 + 6 * s**5
        segments.append(vias[k] + blend * (vias[k + 1] - vias[k]))
    return segments


class _AvoidanceTask(URTask):
    """Shared by the avoidance tasks: delta actions around a reference, shaping terms."""

    rs_mode = "1moving2points"
    scene = "tabletop"
    velocity_scale = 0.2
    action_rate = 20.0
    max_episode_steps = 1000
    limit_status = SUCCESS
    min_distance: ClassVar[float] = 0.3
    collision_reward: ClassVar[float] = -0.1

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self.previous_action = np.zeros(self.action_space.shape[0])

    def server_spec(self) -> tuple[str, str | None, dict[str, str]]:
        robot, scene, options = super().server_spec()
        options["object_0_model_name"] = "sphere50"
        return robot, scene, options

    def reference(self) -> np.ndarray:
        """Joint positions (env order, rad) the action is a delta from."""
        return self.start_joints

    def joint_targets(self, action: np.ndarray) -> np.ndarray:
        """The reference plus the action (rad, un-scaled), fixed joints at the reference."""
        return self.reference() + self.full_action(action, np.zeros(6))

    def _base_obs(self, msg: pb.State) -> list[np.ndarray]:
        """Object in the ee frame (3), normalised joints (6), their offset from the reference."""
        sd = msg.state_dict
        norm = normalize_joints(self.joints(msg))
        return [
            spherical(in_frame(sd, frame_xyz(sd, "object_0"), "ee")),
            norm,
            norm - normalize_joints(self.reference()),
        ]

    def shaping(self, msg: pb.State, action: np.ndarray) -> tuple[float, float]:
        """Per-step terms (x 1/1000) and the object's distance to ee/forearm (m).

        +(1 - offset / (0.1 n)) for staying within 0.1 rad per joint of the reference on
        average, +(1 - mean(a^2)) for small actions, -0.2 per joint whose action jumped by more
        than 0.5 since the last step, -2 when the object is closer than 0.3 m.
        """
        sd = msg.state_dict
        n = action.size
        offset = float(np.abs(self.joints(msg) - self.reference())[self.active].sum())
        reward = max(0.0, 1.0 - offset / (0.1 * n)) + (1.0 - float(np.square(action).mean()))
        reward -= 0.2 * int(np.sum(np.abs(action - self.previous_action) > 0.5))
        obj = frame_xyz(sd, "object_0")
        gap = min(np.linalg.norm(obj - frame_xyz(sd, p)) for p in ("ee", "forearm"))
        if gap < self.min_distance:
            reward -= 2.0
        self.previous_action = action.copy()
        return reward / 1000.0, float(gap)


class BasicAvoidanceUR(_AvoidanceTask):
    """robo-gym's ``BasicAvoidanceURSim-v0`` (spec d.5): hold a pose, dodge a bobbing sphere.

    ## Action space
    ``Box(-1, 1, (5,), float32)`` (wrist_3 fixed): joint offsets in rad from the reset joints
    (un-scaled), env order.

    ## Observation space
    ``Box((18,), float32)``: sphere in the end-effector frame ``[r, theta, phi]`` (3, free),
    normalised joints (6, +-1.1), normalised joints minus normalised reset joints (6, +-1.1),
    3 zeros (bounds [0, 0], kept for robo-gym's layout).

    ## Reward
    ``_AvoidanceTask.shaping`` (about 0.002 per step at best); -0.1 on collision (robo-gym
    ends the episode without a penalty).

    ## Episode end
    terminated: ``collision`` (Sim only); truncated after 1000 steps with final_status
    ``success`` (robo-gym: done), ``server_restarted``.

    ## Reset
    Joints ``[-1.57, -1.31, -1.31, -2.18, 1.57, 0]``; the sphere (object 0) moves on a vertical
    triangle wave at (0.12, 0.34): amplitude ~ U(0.09, 0.35) m, offset ~ U(0.2, 0.6) m, 0.125 Hz.
    Option ``fixed_object_position=[x, y, z]`` holds it still instead.

    ## Arguments
    ``ur_model`` (default ur5), ``fixed_joints``, and ``RobotServerEnv``'s.
    """

    reset_joints = (-1.57, -1.31, -1.31, -2.18, 1.57, 0.0)

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self.observation_space = box(
            [-np.inf] * 3 + [-1.1] * 12 + [0.0] * 3, [np.inf] * 3 + [1.1] * 12 + [0.0] * 3
        )

    def _reset_server(self, client: RobotServerClient, options: Mapping[str, Any]) -> pb.State:
        self.previous_action = np.zeros(self.action_space.shape[0])
        fixed = options.get("fixed_object_position")
        if fixed is not None:
            strings = {"object_0_function": "fixed_position"}
            floats = {f"object_0_{a}": float(v) for a, v in zip("xyz", fixed, strict=True)}
        else:
            strings = {"object_0_function": "triangle_wave"}
            floats = {
                "object_0_x": 0.12,
                "object_0_y": 0.34,
                "object_0_z_frequency": 0.125,
                "object_0_z_amplitude": float(self.np_random.uniform(0.09, 0.35)),
                "object_0_z_offset": float(self.np_random.uniform(0.2, 0.6)),
            }
        return self.set_joints(client, np.array(self.reset_joints), strings, floats)

    def _to_obs(self, msg: pb.State) -> np.ndarray:
        return np.concatenate([*self._base_obs(msg), np.zeros(3)]).astype(np.float32)

    def _evaluate(
        self, msg: pb.State, obs: np.ndarray, action: np.ndarray
    ) -> tuple[float, str | None, StepInfo]:
        reward, gap = self.shaping(msg, action)
        info: StepInfo = {"object_distance": gap}
        if self.collided(msg):
            return reward + self.collision_reward, COLLISION, info
        return reward, None, info


class AvoidanceRaad2022UR(_AvoidanceTask):
    """robo-gym's ``AvoidanceRaad2022URSim-v0`` (spec d.6): follow a reference trajectory while a
    sphere flies through the workspace on a random closed spline.

    The reference trajectory is **a substitute** generated in-repo (``raad_reference_trajectory``):
    robo-gym's ``trajectory_raad_2022.json`` is not available offline. Same segment lengths and
    first waypoint; different path.

    ## Action space
    ``Box(-1, 1, (5,), float32)`` (wrist_3 fixed): joint offsets in rad from the current waypoint.

    ## Observation space
    ``Box((25,), float32)``: indices 0-14 as ``BasicAvoidanceUR`` (offsets from the current
    waypoint), 15-17 the sphere in the forearm_link frame (free), 18-23 the current waypoint
    normalised (+-1.1), 24 the waypoint flag (1 while holding at a segment's end, else 0).

    ## Trajectory
    The waypoint index advances every step; at a segment's last waypoint the env holds until every
    joint is within 0.1 rad of it, then starts the next segment (looping).
    ``info["targets_reached"]`` counts completed segments.

    ## Reward
    ``_AvoidanceTask.shaping`` + 0.05 per completed segment (robo-gym's bonus is never paid);
    -0.1 on collision.

    ## Episode end
    terminated: ``collision`` (Sim only); truncated after 1000 steps with final_status
    ``success``, ``server_restarted``.

    ## Reset
    Joints = the first waypoint. Sphere: ``3d_spline_ur5_workspace`` in [-1, 1]^2 x [0.1, 1] m,
    10 control points, one lap of N ~ U(8000, 12000) samples at 100 Hz.

    ## Arguments
    ``ur_model`` (default ur5), ``fixed_joints``, and ``RobotServerEnv``'s.
    """

    reset_joints = RAAD_START
    segment_tolerance: ClassVar[float] = 0.1
    segment_bonus: ClassVar[float] = 0.05

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self.trajectory = raad_reference_trajectory()
        self.observation_space = box(
            [-np.inf] * 3 + [-1.1] * 12 + [-np.inf] * 3 + [-1.1] * 6 + [0.0],
            [np.inf] * 3 + [1.1] * 12 + [np.inf] * 3 + [1.1] * 6 + [1.0],
        )
        self.segment, self.index, self.targets_reached = 0, 0, 0
        self._completed = 0

    def reference(self) -> np.ndarray:
        return self.trajectory[self.segment][self.index]

    @property
    def holding(self) -> bool:
        return self.index == len(self.trajectory[self.segment]) - 1

    def _reset_server(self, client: RobotServerClient, options: Mapping[str, Any]) -> pb.State:
        self.previous_action = np.zeros(self.action_space.shape[0])
        self.segment, self.index, self.targets_reached = 0, 0, 0
        n = int(self.np_random.uniform(8000, 12000))
        floats = {
            "object_0_x_min": -1.0,
            "object_0_x_max": 1.0,
            "object_0_y_min": -1.0,
            "object_0_y_max": 1.0,
            "object_0_z_min": 0.1,
            "object_0_z_max": 1.0,
            "object_0_n_points": 10.0,
            "object_0_n_sampling_points": float(n),
            "n_sampling_points": float(n),
        }
        strings = {"object_0_function": "3d_spline_ur5_workspace"}
        return self.set_joints(client, np.array(self.reference()), strings, floats)

    def _send(self, client: RobotServerClient, action: np.ndarray) -> pb.State:
        msg = super()._send(client, action)
        # Advance before the observation is made, so it shows the waypoint the next action
        # is relative to.
        self._completed = self._advance(self.joints(msg))
        return msg

    def _to_obs(self, msg: pb.State) -> np.ndarray:
        sd = msg.state_dict
        forearm = spherical(in_frame(sd, frame_xyz(sd, "object_0"), "forearm"))
        ref = normalize_joints(self.reference())
        parts = [*self._base_obs(msg), forearm, ref, [1.0 if self.holding else 0.0]]
        return np.concatenate(parts).astype(np.float32)

    def _evaluate(
        self, msg: pb.State, obs: np.ndarray, action: np.ndarray
    ) -> tuple[float, str | None, StepInfo]:
        reward, gap = self.shaping(msg, action)
        reward += self.segment_bonus * self._completed
        info: StepInfo = {"object_distance": gap, "targets_reached": self.targets_reached}
        if self.collided(msg):
            return reward + self.collision_reward, COLLISION, info
        return reward, None, info

    def _advance(self, joints: np.ndarray) -> int:
        """Move to the next waypoint; returns 1 when a segment was completed on this step."""
        if not self.holding:
            self.index += 1
            return 0
        if np.all(np.abs(joints - self.reference())[self.active] <= self.segment_tolerance):
            self.segment = (self.segment + 1) % len(self.trajectory)
            self.index = 0
            self.targets_reached += 1
            return 1
        return 0
