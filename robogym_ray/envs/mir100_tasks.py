"""MiR100 tasks: navigation to a target, without and with obstacles (robo-gym spec c.1, d.1, d.2).

Both talk to a ``mir100`` robot server (1030-float state). Sim variants use one
SendActionGetState per step; Real variants use SendAction + GetState, which every robo-gym MiR
server answers (older ROS servers lack SendActionGetState).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, ClassVar

import numpy as np
from gymnasium import spaces

from robogym_ray.envs import outcomes
from robogym_ray.envs.base import RobotServerEnv, StepInfo, polar_2d
from robogym_ray.envs.render import RenderConfig
from robogym_ray.envs.render.mir100 import draw_mir100
from robogym_ray.errors import InvalidStateError
from robogym_ray.protocol import robot_server_pb2 as pb
from robogym_ray.protocol.client import RobotServerClient

STATE_LEN = 1030
LASER = slice(8, 1020)
COLLISION = 1020
OBSTACLES = slice(1021, 1030)
MAX_V, MAX_W = 0.5, 0.7
"""Action scale: env action [-1, 1]^2 -> (m/s, rad/s) sent to the server (spec c.1)."""
LASER_OFFSETS = np.round(np.linspace(0, 1011, 16)).astype(int)
"""The 16 laser values of the observation: these offsets into the 1012 raw ranges (spec d.2)."""


class _Mir100Task(RobotServerEnv):
    """Shared MiR100 machinery: SetState vector, polar observation, distance shaping."""

    scene: ClassVar[str]
    success_distance: ClassVar[float] = 0.2
    success_reward: ClassVar[float] = 200.0
    distance_weight: ClassVar[float] = 50.0

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self.action_space = spaces.Box(-1.0, 1.0, shape=(2,), dtype=np.float32)
        self.target = np.zeros(3)
        self._prev_distance = 0.0

    def server_spec(self) -> tuple[str, str | None, dict[str, str]]:
        return "mir100", self.scene, {}

    # -- episode start ---------------------------------------------------------------------
    def _reset_server(self, client: RobotServerClient, options: Mapping[str, Any]) -> pb.State:
        if self.real_robot:  # the real robot starts where it stands
            start = self._pose(self._checked(client.get_state()))
        elif options.get("start_pose") is not None:
            start = np.asarray(options["start_pose"], dtype=np.float64)
        else:
            start = self._sample_start()
        target = options.get("target_pose")
        self.target = (
            np.asarray(target, dtype=np.float64)
            if target is not None
            else self._sample_target(start)
        )
        self.target[2] = 0.0
        vec = np.zeros(STATE_LEN)
        vec[0:3], vec[3:6] = self.target, start
        vec[OBSTACLES] = self._obstacle_vector()
        client.set_state(pb.State(state=vec.astype(np.float32).tolist()))
        msg = self._checked(client.get_state())
        self._prev_distance = self._distance(msg)
        return msg

    def _sample_start(self) -> np.ndarray:
        raise NotImplementedError

    def _sample_target(self, start: np.ndarray) -> np.ndarray:
        raise NotImplementedError

    def placed_obstacles(self) -> np.ndarray | None:
        """The cubes this episode's SetState placed, one (x, y, yaw) row each; None when the
        task has none, or on a real robot (its cubes are where they stand)."""
        return None

    def _obstacle_vector(self) -> np.ndarray:
        placed = self.placed_obstacles()
        return np.zeros(9) if placed is None else placed.ravel()

    # -- frames ----------------------------------------------------------------------------
    def _position(self, msg: pb.State) -> np.ndarray:
        return self._pose(msg)[:2]

    def _on_state(self, msg: pb.State, reset: bool) -> None:
        if reset:
            self._path: list[np.ndarray] = []
        self._path.append(self._position(msg))

    def _draw(self, msg: pb.State, cfg: RenderConfig) -> np.ndarray:
        caption = f"{type(self).__name__}  step {self.elapsed_steps}"
        path = np.array(getattr(self, "_path", []))
        return draw_mir100(
            msg.state,
            cfg,
            walls=self.scene == "lab_6x8",
            obstacles=self._obstacle_vector(),  # what SetState placed (zeros on a real robot)
            path=path,
            caption=caption,
        )

    # -- stepping --------------------------------------------------------------------------
    def _send(self, client: RobotServerClient, action: np.ndarray) -> pb.State:
        command = action * np.array([MAX_V, MAX_W])
        if self.real_robot:
            client.send_action(command)
            return self._checked(client.get_state())
        return self._checked(client.send_action_get_state(command))

    def _checked(self, msg: pb.State) -> pb.State:
        if len(msg.state) != STATE_LEN:
            raise InvalidStateError(
                f"Robot Server state received has wrong length: {len(msg.state)} values, "
                f"expected {STATE_LEN} (MiR100 layout, spec c.1; {self._where()})"
            )
        return msg

    @staticmethod
    def _pose(msg: pb.State) -> np.ndarray:
        return np.asarray(msg.state[3:6], dtype=np.float64)

    def _distance(self, msg: pb.State) -> float:
        state = msg.state
        return float(np.hypot(state[0] - state[3], state[1] - state[4]))

    def _nav_obs(self, msg: pb.State) -> np.ndarray:
        s = msg.state
        r, theta = polar_2d(s[0] - s[3], s[1] - s[4], s[5])
        return np.array([r, theta, s[6], s[7]], dtype=np.float32)

    def _shaping(self, msg: pb.State, action: np.ndarray) -> tuple[float, float]:
        """(reward for progress and power use, current distance)."""
        distance = self._distance(msg)
        reward = self.distance_weight * (self._prev_distance - distance)
        reward -= 0.3 * abs(action[0]) + 0.03 * abs(action[1])
        self._prev_distance = distance
        return reward, distance


_NAV_LOW = [0.0, -np.pi, -1.1, -1.6]
_NAV_HIGH = [np.inf, np.pi, 1.1, 1.6]


class NoObstacleNavigationMir100(_Mir100Task):
    """Drive the MiR100 to a target in an empty world (robo-gym d.1).

    ## Action space
    ``Box(-1, 1, (2,), float32)``: target linear and angular velocity, scaled by 0.5 m/s and
    0.7 rad/s.

    ## Observation space
    ``Box((4,), float32)``

    | index | meaning | bounds |
    |---|---|---|
    | 0 | distance robot -> target (m) | [0, inf) |
    | 1 | bearing of the target in the robot frame (rad) | [-pi, pi] |
    | 2, 3 | linear (m/s) and angular (rad/s) velocity | [-1.1, 1.1], [-1.6, 1.6] |

    ## Reward
    ``50 * (previous distance - distance) - 0.3 |a0| - 0.03 |a1|`` per step (the first step
    counts from the reset distance; robo-gym gives 0 there); +200 on reaching the target
    (distance < 0.2 m); -200 when leaving the 20 x 20 m boundary (|x| > 10 or |y| > 10;
    robo-gym omits the ``abs`` on y).

    ## Episode end
    terminated: ``success`` or ``out of boundary``; truncated: ``max_steps_exceeded`` after
    ``max_episode_steps`` (500); ``server_restarted`` (Sim only, see ``RobotServerEnv``).

    ## Reset
    Start (x, y) ~ U[-2, 2]^2, yaw ~ U[-pi, pi] (Real: the current pose); target ~ U[-1, 1]^2 at
    least 1 m away. ``reset(options={"start_pose": [x, y, yaw], "target_pose": [x, y, 0]})``.

    ## Arguments
    See ``RobotServerEnv`` (real_robot, rs_address, provider, token, tls_ca, deadlines,
    server_seed, max_steps).
    """

    scene = "empty"
    max_episode_steps = 500

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self.observation_space = spaces.Box(
            np.array(_NAV_LOW, np.float32), np.array(_NAV_HIGH, np.float32), dtype=np.float32
        )

    def _sample_start(self) -> np.ndarray:
        rng = self.np_random
        return np.array([*rng.uniform(-2.0, 2.0, 2), rng.uniform(-np.pi, np.pi)])

    def _sample_target(self, start: np.ndarray) -> np.ndarray:
        while True:
            xy = self.np_random.uniform(-1.0, 1.0, 2)
            if np.hypot(*(xy - start[:2])) >= 1.0:
                return np.array([xy[0], xy[1], 0.0])

    def _to_obs(self, msg: pb.State) -> np.ndarray:
        return self._nav_obs(msg)

    def _evaluate(
        self, msg: pb.State, obs: np.ndarray, action: np.ndarray
    ) -> tuple[float, str | None, StepInfo]:
        reward, distance = self._shaping(msg, action)
        x, y = msg.state[3], msg.state[4]
        if distance < self.success_distance:
            return reward + self.success_reward, outcomes.SUCCESS, {}
        if abs(x) > 10.0 or abs(y) > 10.0:
            return reward - 200.0, "out of boundary", {}
        return reward, None, {}


class ObstacleAvoidanceMir100(_Mir100Task):
    """Problem 1 of the paper: cross the 6 x 8 m lab to a target, avoiding three cubes (d.2).

    ## Action space
    ``Box(-1, 1, (2,), float32)``: target linear and angular velocity, scaled by 0.5 m/s and
    0.7 rad/s.

    ## Observation space
    ``Box((20,), float32)``: indices 0-3 as in ``NoObstacleNavigationMir100``; 4-19 = 16 laser
    ranges (m, [0, 29]) = raw ranges ``state[8:1020]`` at offsets ``round(linspace(0, 1011,
    16))`` (front scanner -75 deg ... back scanner -10 deg, counter-clockwise).

    ## Reward
    ``50 * (previous distance - distance) - 0.3 |a0| - 0.03 |a1|`` per step; +100 on reaching the
    target (< 0.2 m); -200 on collision.

    ## Episode end
    terminated: ``success`` or ``collision``; truncated: ``max_steps_exceeded`` after 500 steps,
    ``server_restarted`` (Sim only). Collision (Sim): the bumper flag ``state[1020] == 1``, any
    raw laser range < 0.15 m, or a corner of the 0.9 x 0.58 m footprint within 0.40 m of an
    obstacle centre. Real: only the laser test (the real robot senses nothing else; robo-gym
    checks nothing on the real robot).

    ## Reset
    The robot starts on one side of the lab (x ~ U[-2, 2], y ~ U[2.1, 3.1] or U[-3.1, -2.1],
    side drawn from ``np_random``, yaw ~ U[-pi, pi]); the target lies in the band on the opposite
    side, at least 1 m away; cubes (x, y, yaw): x ~ U[-2.4, -1.5], U[-0.5, 0.5], U[1.5, 2.4],
    y ~ U[-1, 1], yaw ~ U[-pi, pi]. Real: start = current pose, no cubes are placed.
    Options ``start_pose``, ``target_pose``, ``obstacles`` ([[x, y, yaw]] * 3) override.

    ## Arguments
    See ``RobotServerEnv``.
    """

    scene = "lab_6x8"
    max_episode_steps = 500
    success_reward = 100.0
    collision_reward: ClassVar[float] = -200.0
    laser_collision: ClassVar[float] = 0.15
    obstacle_clearance: ClassVar[float] = 0.40

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        low = np.array(_NAV_LOW + [0.0] * 16, np.float32)
        high = np.array(_NAV_HIGH + [29.0] * 16, np.float32)
        self.observation_space = spaces.Box(low, high, dtype=np.float32)
        self.obstacles = np.zeros((3, 3))
        self._side = 1.0

    def _reset_server(self, client: RobotServerClient, options: Mapping[str, Any]) -> pb.State:
        self._side = 1.0 if self.np_random.random() < 0.5 else -1.0
        if options.get("obstacles") is not None:
            self.obstacles = np.asarray(options["obstacles"], dtype=np.float64).reshape(3, 3)
        else:
            self.obstacles = self._sample_obstacles()
        return super()._reset_server(client, options)

    def _sample_start(self) -> np.ndarray:
        rng = self.np_random
        y = self._side * rng.uniform(2.1, 3.1)
        return np.array([rng.uniform(-2.0, 2.0), y, rng.uniform(-np.pi, np.pi)])

    def _sample_target(self, start: np.ndarray) -> np.ndarray:
        side = -1.0 if start[1] > 0 else 1.0
        while True:
            xy = np.array(
                [self.np_random.uniform(-2.0, 2.0), side * self.np_random.uniform(2.1, 3.1)]
            )
            if np.hypot(*(xy - start[:2])) >= 1.0:
                return np.array([xy[0], xy[1], 0.0])

    def _sample_obstacles(self) -> np.ndarray:
        rng = self.np_random
        xs = [rng.uniform(-2.4, -1.5), rng.uniform(-0.5, 0.5), rng.uniform(1.5, 2.4)]
        return np.array([[x, rng.uniform(-1.0, 1.0), rng.uniform(-np.pi, np.pi)] for x in xs])

    def placed_obstacles(self) -> np.ndarray | None:
        return None if self.real_robot else self.obstacles

    def _to_obs(self, msg: pb.State) -> np.ndarray:
        lasers = np.asarray(msg.state[LASER], dtype=np.float32)[LASER_OFFSETS]
        return np.concatenate([self._nav_obs(msg), lasers])

    def _evaluate(
        self, msg: pb.State, obs: np.ndarray, action: np.ndarray
    ) -> tuple[float, str | None, StepInfo]:
        reward, distance = self._shaping(msg, action)
        if self._collided(msg):
            return reward + self.collision_reward, outcomes.COLLISION, {}
        if distance < self.success_distance:
            return reward + self.success_reward, outcomes.SUCCESS, {}
        return reward, None, {}

    def _collided(self, msg: pb.State) -> bool:
        if min(msg.state[LASER]) < self.laser_collision:
            return True
        if self.real_robot:
            return False
        return msg.state[COLLISION] == 1.0 or self._footprint_hits(self._pose(msg))

    def _footprint_hits(self, pose: np.ndarray) -> bool:
        x, y, yaw = pose
        c, s = np.cos(yaw), np.sin(yaw)
        half = np.array([[0.45, 0.29], [0.45, -0.29], [-0.45, 0.29], [-0.45, -0.29]])
        corners = np.stack(
            [x + c * half[:, 0] - s * half[:, 1], y + s * half[:, 0] + c * half[:, 1]], 1
        )
        gaps = np.linalg.norm(corners[:, None, :] - self.obstacles[None, :, :2], axis=2)
        return bool(np.any(gaps < self.obstacle_clearance))
