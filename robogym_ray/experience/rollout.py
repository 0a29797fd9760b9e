"""Rollout worker (plain class): env + CPU policy copy + exploration + n-step accumulator.

The Ray program wraps it in an actor; tests drive it directly. One ``collect`` call runs a fixed
number of env steps and returns the finished n-step transitions, the episodes that ended, and
counters. When the robot server fails mid-episode (the env ends the episode with
``final_status == "server_restarted"``), the unfinished n-step window is dropped, so no
transition in replay ever spans a crash.
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

import gymnasium as gym
import numpy as np

from robogym_ray.envs.outcomes import ROBOT_ERROR, SERVER_RESTARTED
from robogym_ray.errors import ConfigError, RobotServerError
from robogym_ray.experience.revisits import FailedStartRevisits
from robogym_ray.learner.behaviour import BehaviourPolicy, to_env_action
from robogym_ray.learner.config import D4PGConfig
from robogym_ray.learner.nstep import NStepAccumulator, Transition, stack_transitions

log = logging.getLogger(__name__)

EnvFactory = Callable[[], gym.Env]


@dataclass(frozen=True)
class Episode:
    """Summary of one finished episode."""

    ret: float
    length: int
    final_status: str
    worker: int
    revisit: bool = False
    """The episode re-ran the start of one this worker failed earlier (``revisits.py``)."""


@dataclass
class RolloutResult:
    """What one ``collect`` call sends back to the driver."""

    batch: dict[str, np.ndarray] | None
    """Stacked n-step transitions (None when none completed)."""
    episodes: list[Episode] = field(default_factory=list)
    steps: int = 0
    dropped: int = 0
    """Steps whose n-step window was dropped because the server failed mid-episode."""
    weights_version: int = -1
    wall_s: float = 0.0
    worker: int = 0
    robot_errors: int = 0
    """Failed calls to a real robot (which is never restarted; the worker waits for it)."""
    paused: bool = False
    """The robot could not start an episode (e.g. paused by its operator): try again later."""


def box_dims(env: gym.Env) -> tuple[int, int]:
    """(obs_dim, act_dim) of an env with flat Box spaces; ConfigError otherwise."""
    obs, act = env.observation_space, env.action_space
    if not (isinstance(obs, gym.spaces.Box) and isinstance(act, gym.spaces.Box)):
        raise ConfigError(f"D4PG needs Box observation and action spaces, got {obs} and {act}")
    if len(obs.shape) != 1 or len(act.shape) != 1:
        raise ConfigError(f"D4PG needs flat spaces, got shapes {obs.shape} and {act.shape}")
    return int(obs.shape[0]), int(act.shape[0])


class RolloutWorker:
    """Collects n-step experience with a noisy copy of the policy."""

    def __init__(
        self,
        make_env: EnvFactory,
        d4pg: D4PGConfig,
        *,
        index: int = 0,
        sigma: float | None = None,
        seed: int = 0,
        random_steps: int = 0,
        revisits: FailedStartRevisits | None = None,
    ) -> None:
        """Args:
        make_env: builds this worker's env (Sim via a server provider, or Real by address).
        d4pg: network shapes, n-step length and discount.
        index: worker number (for logs and episode records).
        sigma: this worker's exploration noise (Ape-X gives each actor its own); None = d4pg's.
        seed: env and noise seed.
        random_steps: first steps taken with uniform random actions (before any weights).
        revisits: re-run the starts of failed episodes; every reset is then seeded from it.
        """
        self.env = make_env()
        self.index = index
        obs_dim, act_dim = box_dims(self.env)
        self.low = self.env.action_space.low.astype(np.float64)
        self.high = self.env.action_space.high.astype(np.float64)
        self.sigma = d4pg.sigma if sigma is None else sigma
        self.actor = BehaviourPolicy(
            obs_dim,
            act_dim,
            d4pg.policy_hidden,
            self.sigma,
            d4pg.layer_norm,
            seed=seed,
        )
        self.nstep = NStepAccumulator(d4pg.n_step, d4pg.discount)
        self.random_steps = random_steps
        self.rng = np.random.default_rng(seed + 7919)
        self.weights_version = -1
        self.total_steps = 0
        self.retry_wait_s = 1.0
        self.revisits = revisits
        self._start = revisits.next_start() if revisits else (seed, False)
        self.obs: np.ndarray | None = self.env.reset(seed=self._start[0])[0]
        self._ret, self._len = 0.0, 0

    def set_weights(self, weights: Mapping[str, np.ndarray], version: int) -> None:
        self.actor.set_weights(dict(weights))
        self.weights_version = version

    def _action(self) -> np.ndarray:
        if self.weights_version < 0 or self.total_steps < self.random_steps:
            return self.rng.uniform(-1.0, 1.0, self.actor.act_dim).astype(np.float32)
        return self.actor.act(np.asarray(self.obs, dtype=np.float32), explore=True)

    def collect(self, num_steps: int, noise_scale: float = 1.0) -> RolloutResult:
        """Run ``num_steps`` env steps with ``noise_scale`` times this worker's sigma; return
        completed transitions and finished episodes."""
        if not (math.isfinite(noise_scale) and noise_scale >= 0):
            raise ValueError(f"worker {self.index}: noise_scale {noise_scale!r}; expected >= 0")
        self.actor.sigma = self.sigma * noise_scale
        start = time.perf_counter()
        out: list[Transition] = []
        result = RolloutResult(batch=None, worker=self.index, weights_version=self.weights_version)
        for _ in range(num_steps):
            if self.obs is None and not self._try_reset(result):
                break
            action = self._action()
            try:
                next_obs, reward, terminated, truncated, info = self.env.step(
                    to_env_action(action, self.low, self.high)
                )
            except RobotServerError as exc:
                # Real robots raise instead of restarting: abandon the episode (and its
                # unfinished n-step window) and start a new one once the robot answers.
                self._abandon(result, exc)
                continue
            result.steps += 1
            self._ret += float(reward)
            self._len += 1
            status = str(info.get("final_status", ""))
            if status == SERVER_RESTARTED:
                # The episode was cut by a crash: its pending window would bootstrap across it.
                result.dropped += self.nstep.drop() + 1
            else:
                out += self.nstep.push(
                    self.obs, action, float(reward), next_obs, bool(terminated), bool(truncated)
                )
            self.obs = next_obs
            if terminated or truncated or status == SERVER_RESTARTED:
                ended = status or ("truncated" if truncated else "terminated")
                result.episodes.append(
                    Episode(self._ret, self._len, ended, self.index, self._start[1])
                )
                if self.revisits is not None:
                    self.revisits.record(*self._start, status)
                self._ret, self._len = 0.0, 0
                self.nstep.drop()  # nothing may carry over into the next episode
                self.obs = None  # the next step resets (a real robot's reset may fail)
        self.total_steps += result.steps
        result.batch = stack_transitions(out) if out else None
        result.wall_s = time.perf_counter() - start
        return result

    def _abandon(self, result: RolloutResult, exc: RobotServerError) -> None:
        log.warning("worker %d: robot error, episode abandoned: %s", self.index, exc)
        result.robot_errors += 1
        result.dropped += self.nstep.drop()
        result.episodes.append(
            Episode(self._ret, self._len, ROBOT_ERROR, self.index, self._start[1])
        )
        self._ret, self._len = 0.0, 0
        self.obs = None

    def _try_reset(self, result: RolloutResult) -> bool:
        start = self.revisits.next_start() if self.revisits else None
        try:
            self.obs, _ = self.env.reset(seed=None if start is None else start[0])
            self._start = start or (-1, False)
            return True
        except RobotServerError as exc:
            log.warning("worker %d: robot not ready (%s); retrying later", self.index, exc)
            result.paused = True
            time.sleep(self.retry_wait_s)  # don't spin on a paused robot
            return False

    def ping(self) -> int:
        return self.total_steps

    def close(self) -> None:
        self.env.close()


def make_gym_env(env_id: str, env_kwargs: Mapping[str, Any] | None = None) -> EnvFactory:
    """An EnvFactory for a registered Gymnasium id (importing robogym_ray registers ours)."""

    def factory() -> gym.Env:
        import robogym_ray  # noqa: F401 - registers the RoboGymRay/* ids

        return gym.make(env_id, **dict(env_kwargs or {}))

    return factory
