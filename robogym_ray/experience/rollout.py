"""Rollout worker (plain class): K envs + CPU policy copy + exploration + n-step accumulators.

The Ray program wraps it in an actor; tests drive it directly. One ``collect`` call runs a fixed
number of env steps (one batched policy forward per round of the K envs) and returns the finished
n-step transitions, the episodes that ended, and counters. When the robot server fails
mid-episode (the env ends the episode with ``final_status == "server_restarted"``), the unfinished
n-step window is dropped, so no transition in replay ever spans a crash.
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
from robogym_ray.experience.relabel import HindsightRelabeller, goal_task
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
    """Stacked n-step transitions (None when none completed), relabelled ones included."""
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
    faults: dict[str, int] = field(default_factory=dict)
    """Server faults that ended episodes, by the client's cause (``deadline``, ``rejected`` ...)."""
    transitions: int = 0
    """n-step transitions completed (in ``batch``, or already sent to the learner)."""
    relabelled: int = 0
    """Of ``transitions``, those written by hindsight relabelling (``relabel.py``)."""
    learner_call: Any = None
    """The learner's answer to this batch when the worker sent it itself (a Ray reference)."""


def box_dims(env: gym.Env) -> tuple[int, int]:
    """(obs_dim, act_dim) of an env with flat Box spaces; ConfigError otherwise."""
    obs, act = env.observation_space, env.action_space
    if not (isinstance(obs, gym.spaces.Box) and isinstance(act, gym.spaces.Box)):
        raise ConfigError(f"D4PG needs Box observation and action spaces, got {obs} and {act}")
    if len(obs.shape) != 1 or len(act.shape) != 1:
        raise ConfigError(f"D4PG needs flat spaces, got shapes {obs.shape} and {act.shape}")
    return int(obs.shape[0]), int(act.shape[0])


ENV_SEED_STRIDE = 100_003
"""Env k of a worker seeded ``seed`` first resets with ``seed + k * ENV_SEED_STRIDE`` (a prime far
above any worker count, so the envs of different workers never share a first episode)."""


@dataclass
class EnvSlot:
    """One of a worker's envs and what is pending on it: its observation (None: it needs a
    reset), its n-step window and the running episode's return and length."""

    env: gym.Env
    nstep: NStepAccumulator
    obs: np.ndarray | None = None
    start: tuple[int, bool] = (-1, False)
    """(seed, revisit) the running episode started from."""
    pending_start: tuple[int, bool] | None = None
    """A start chosen but not reset into yet: the robot was not ready when the worker began."""
    ret: float = 0.0
    length: int = 0
    relabeller: HindsightRelabeller | None = None
    """The running episode's steps, relabelled when it ends (``relabel_goals``)."""


class RolloutWorker:
    """Collects n-step experience from K envs with a noisy copy of the policy.

    Every step is one batched policy forward for the envs that are running, then one step of
    each; episodes end independently, each env has its own n-step window, and an env whose
    episode ended resets before its next step.
    """

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
        num_envs: int = 1,
        real_robot: bool = False,
        relabel_goals: int = 0,
    ) -> None:
        """Args:
        make_env: builds one of this worker's envs (Sim via a server provider, or Real).
        d4pg: network shapes, n-step length and discount.
        index: worker number (for logs and episode records).
        sigma: this worker's exploration noise (Ape-X gives each actor its own); None = d4pg's.
        seed: env and noise seed.
        random_steps: first steps taken with uniform random actions (before any weights).
        revisits: re-run the starts of failed episodes; every reset is then seeded from it.
        num_envs: envs stepped together (K), with one batched policy forward per step.
        real_robot: its env reaches a real robot. One that does not answer the first reset
            (paused, its server down) is retried by ``collect`` as at any later reset, rather
            than failing the worker: a real robot's worker is never replaced. A simulated
            worker's first reset raises, so that a new worker and server take its place.
        relabel_goals: relabelled copies of each step under commands the episode reached
            later (hindsight relabelling, ``relabel.py``; the task must be a goal task);
            0 = off.
        """
        if num_envs < 1:
            raise ConfigError(f"worker {index}: num_envs={num_envs}; expected >= 1")
        self.make_env = make_env
        self.slots = [EnvSlot(make_env(), NStepAccumulator(d4pg.n_step, d4pg.discount))
                      for _ in range(num_envs)]  # fmt: skip
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
        self.random_steps = random_steps
        self.rng = np.random.default_rng(seed + 7919)
        self.weights_version = -1
        self.total_steps = 0
        self.retry_wait_s = 1.0
        self.revisits = revisits
        for k, slot in enumerate(self.slots if relabel_goals else ()):
            slot.relabeller = HindsightRelabeller(
                goal_task(slot.env), relabel_goals, d4pg.n_step, d4pg.discount,
                np.random.default_rng([seed, k, 4057]),
            )  # fmt: skip
        for k, slot in enumerate(self.slots):
            slot.start = revisits.next_start() if revisits else (seed + k * ENV_SEED_STRIDE, False)
            try:
                slot.obs = slot.env.reset(seed=slot.start[0])[0]
            except RobotServerError as exc:
                if not real_robot:
                    raise
                log.warning("worker %d: robot not ready at the start (%s); retrying in its "
                            "first collect", index, exc)  # fmt: skip
                slot.pending_start = slot.start
                self._renew_env(slot)

    @property
    def env(self) -> gym.Env:
        """The first env (its spaces are every env's): the slot's own, renewed with it."""
        return self.slots[0].env

    def set_weights(self, weights: Mapping[str, np.ndarray], version: int) -> None:
        self.actor.set_weights(dict(weights))
        self.weights_version = version

    def _actions(self, obs: np.ndarray) -> np.ndarray:
        if self.weights_version < 0 or self.total_steps < self.random_steps:
            return self.rng.uniform(-1.0, 1.0, (len(obs), self.actor.act_dim)).astype(np.float32)
        return self.actor.act_batch(obs, explore=True)

    def collect(self, num_steps: int, noise_scale: float = 1.0) -> RolloutResult:
        """Run at least ``num_steps`` env steps over the K envs (rounded up to whole rounds of
        the running envs) with ``noise_scale`` times this worker's sigma; return completed
        transitions and finished episodes."""
        if not (math.isfinite(noise_scale) and noise_scale >= 0):
            raise ValueError(f"worker {self.index}: noise_scale {noise_scale!r}; expected >= 0")
        self.actor.sigma = self.sigma * noise_scale
        start = time.perf_counter()
        out: list[Transition] = []
        result = RolloutResult(batch=None, worker=self.index, weights_version=self.weights_version)
        while result.steps < num_steps:
            running = [s for s in self.slots if s.obs is not None or self._try_reset(s, result)]
            if not running:
                break
            actions = self._actions(np.stack([s.obs for s in running]).astype(np.float32))
            for slot, action in zip(running, actions, strict=True):
                self._step(slot, action, result, out)
        self.total_steps += result.steps
        result.batch = stack_transitions(out) if out else None
        result.transitions = len(out)
        result.wall_s = time.perf_counter() - start
        return result

    def _step(
        self, slot: EnvSlot, action: np.ndarray, result: RolloutResult, out: list[Transition]
    ) -> None:
        try:
            next_obs, reward, terminated, truncated, info = slot.env.step(
                to_env_action(action, self.low, self.high)
            )
        except RobotServerError as exc:
            # Real robots raise instead of restarting: abandon the episode (and its
            # unfinished n-step window) and start a new one once the robot answers.
            self._abandon(slot, result, exc)
            return
        result.steps += 1
        slot.ret += float(reward)
        slot.length += 1
        status = str(info.get("final_status", ""))
        if status == SERVER_RESTARTED:
            # The episode was cut by a crash: its pending window would bootstrap across it.
            result.dropped += slot.nstep.drop() + 1
            fault = str(info.get("fault", "other"))
            result.faults[fault] = result.faults.get(fault, 0) + 1
            if slot.relabeller is not None:
                slot.relabeller.drop()  # no relabelled window spans the crash either
        else:
            out += slot.nstep.push(
                slot.obs, action, float(reward), next_obs, bool(terminated), bool(truncated)
            )
            if slot.relabeller is not None:
                slot.relabeller.record(slot.obs, action, next_obs, info)
                if terminated or truncated:
                    relabelled = slot.relabeller.finish(bool(terminated))
                    result.relabelled += len(relabelled)
                    out += relabelled
        slot.obs = next_obs
        if terminated or truncated or status == SERVER_RESTARTED:
            ended = status or ("truncated" if truncated else "terminated")
            result.episodes.append(Episode(slot.ret, slot.length, ended, self.index, slot.start[1]))
            if self.revisits is not None:
                self.revisits.record(*slot.start, status)
            slot.ret, slot.length = 0.0, 0
            slot.nstep.drop()  # nothing may carry over into the next episode
            slot.obs = None  # the next step resets (a real robot's reset may fail)

    def _abandon(self, slot: EnvSlot, result: RolloutResult, exc: RobotServerError) -> None:
        log.warning("worker %d: robot error, episode abandoned: %s", self.index, exc)
        result.robot_errors += 1
        result.dropped += slot.nstep.drop()
        if slot.relabeller is not None:
            slot.relabeller.drop()
        result.episodes.append(
            Episode(slot.ret, slot.length, ROBOT_ERROR, self.index, slot.start[1])
        )
        slot.ret, slot.length = 0.0, 0
        slot.obs = None

    def _try_reset(self, slot: EnvSlot, result: RolloutResult) -> bool:
        start = slot.pending_start or (self.revisits.next_start() if self.revisits else None)
        try:
            slot.obs, _ = slot.env.reset(seed=None if start is None else start[0])
            slot.start, slot.pending_start = start or (-1, False), None
            return True
        except RobotServerError as exc:
            log.warning("worker %d: robot not ready (%s); retrying later", self.index, exc)
            if slot.pending_start is not None:
                self._renew_env(slot)
            result.paused = True
            time.sleep(self.retry_wait_s)  # don't spin on a paused robot
            return False

    def _renew_env(self, slot: EnvSlot) -> None:
        """A new env in place of one whose first reset raised: gymnasium's passive env checker
        takes that reset as its checked first one, then fails the first step (gymnasium 1.4)."""
        slot.env.close()
        slot.env = self.make_env()
        if slot.relabeller is not None:
            slot.relabeller.task = goal_task(slot.env)

    def ping(self) -> int:
        return self.total_steps

    def close(self) -> None:
        for slot in self.slots:
            slot.env.close()


def make_gym_env(env_id: str, env_kwargs: Mapping[str, Any] | None = None) -> EnvFactory:
    """An EnvFactory for a registered Gymnasium id (importing robogym_ray registers ours)."""

    def factory() -> gym.Env:
        import robogym_ray  # noqa: F401 - registers the RoboGymRay/* ids

        return gym.make(env_id, **dict(env_kwargs or {}))

    return factory
