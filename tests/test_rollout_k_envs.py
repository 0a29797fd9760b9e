"""A rollout worker with K envs: each env's n-step transitions are exactly what one env alone
gives, although episodes of different lengths end in different rounds."""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
import pytest

from robogym_ray.errors import ConfigError
from robogym_ray.experience.rollout import ENV_SEED_STRIDE, RolloutWorker
from robogym_ray.learner.config import D4PGConfig
from robogym_ray.learner.nstep import NStepAccumulator


class Counting(gym.Env[np.ndarray, np.ndarray]):
    """obs = (env number, step, episode); reward depends on both; the episode length on the
    reset seed (2-6 steps), ending terminated or truncated by turns. Records its trajectory."""

    observation_space = gym.spaces.Box(-1e6, 1e6, (3,), np.float32)
    action_space = gym.spaces.Box(-1.0, 1.0, (1,), np.float32)
    made = 0

    def __init__(self) -> None:
        self.number = Counting.made
        Counting.made += 1
        self.episode = -1
        self.trajectory: list[tuple[Any, ...]] = []

    def _obs(self) -> np.ndarray:
        return np.array([self.number, self.t, self.episode], np.float32)

    def reset(self, *, seed: int | None = None, options: Any = None) -> tuple[np.ndarray, dict]:
        super().reset(seed=seed)
        self.episode += 1
        self.t, self.length = 0, 2 + int(self.np_random.integers(0, 5))
        return self._obs(), {}

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict]:
        before = self._obs()
        self.t += 1
        reward = float(self.t + 10 * self.number + 0.5 * action[0])
        end = self.t >= self.length
        terminated, truncated = end and self.episode % 2 == 0, end and self.episode % 2 == 1
        after = self._obs()
        self.trajectory.append((before, np.asarray(action), reward, after, terminated, truncated))
        return after, reward, terminated, truncated, {}


def test_k_env_transitions_equal_each_env_alone() -> None:
    d4pg = D4PGConfig(n_step=3, discount=0.9)
    Counting.made = 0
    worker = RolloutWorker(Counting, d4pg, seed=1, num_envs=3, random_steps=10_000)
    result = worker.collect(200)
    assert result.steps >= 200 and result.transitions == len(result.batch["reward"])
    ends = {}
    for ep in result.episodes:
        ends.setdefault(ep.length, 0)
        ends[ep.length] += 1
    assert len(ends) > 1  # episodes of different lengths: they end in different rounds
    batch = result.batch
    for slot in worker.slots:
        env = slot.env
        alone = NStepAccumulator(d4pg.n_step, d4pg.discount)
        expected = []
        for obs, action, reward, nxt, term, trunc in env.trajectory:
            # The worker stores actions on the policy's [-1, 1] scale: the same as this Box's.
            expected += alone.push(obs, action, reward, nxt, term, trunc)
        mine = batch["obs"][:, 0] == env.number
        assert mine.sum() == len(expected) > 10
        np.testing.assert_allclose(batch["obs"][mine], [t.obs for t in expected])
        np.testing.assert_allclose(batch["action"][mine], [t.action for t in expected], atol=1e-6)
        np.testing.assert_allclose(batch["reward"][mine], [t.reward for t in expected], rtol=1e-6)
        np.testing.assert_allclose(batch["discount"][mine], [t.discount for t in expected])
        np.testing.assert_allclose(batch["next_obs"][mine], [t.next_obs for t in expected])
        # No transition crosses an episode boundary.
        assert (batch["obs"][mine][:, 2] == batch["next_obs"][mine][:, 2]).all()
        # What is still pending is exactly the open window of the running episode.
        assert len(slot.nstep) == len(alone)


def test_the_first_resets_of_k_envs_use_distinct_seeds() -> None:
    Counting.made = 0
    worker = RolloutWorker(Counting, D4PGConfig(), seed=4, num_envs=4)
    seeds = [slot.start[0] for slot in worker.slots]
    assert seeds == [4 + k * ENV_SEED_STRIDE for k in range(4)]


@pytest.mark.parametrize("bad", [0, -2])
def test_num_envs_must_be_positive(bad: int) -> None:
    with pytest.raises(ConfigError, match="num_envs"):
        RolloutWorker(Counting, D4PGConfig(), num_envs=bad)
