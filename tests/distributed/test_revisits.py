"""Revisiting failed starts: the pool's rules, and a rollout worker re-running a real Sim scene."""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
import pytest

from robogym_ray.errors import ConfigError
from robogym_ray.experience.revisits import FIRST_SEED, FailedStartRevisits
from robogym_ray.experience.rollout import RolloutWorker
from robogym_ray.learner.config import D4PGConfig
from robogym_ray.training.config import TrainConfig
from robogym_ray.training.program import revisits_for

SMALL = D4PGConfig(policy_hidden=(16, 16), critic_hidden=(16, 16), batch_size=8)


def test_failures_are_pooled_and_retired_when_solved_or_used_up() -> None:
    revisits = FailedStartRevisits(1.0, capacity=2, max_revisits=2, seed=3)
    first, revisit = revisits.next_start()
    assert not revisit and FIRST_SEED <= first < 2**31  # never an evaluation seed
    revisits.record(first, False, "collision")
    assert revisits.next_start() == (first, True)  # probability 1: the pooled start
    revisits.record(first, True, "max_steps_exceeded")
    assert revisits.next_start() == (first, True)
    revisits.record(first, True, "collision")  # second revisit failed too: used up
    assert revisits.pool == {}
    fresh, revisit = revisits.next_start()
    assert not revisit and fresh != first
    revisits.record(fresh, False, "collision")
    assert revisits.next_start() == (fresh, True)
    revisits.record(fresh, True, "success")  # solved: retired at once
    assert revisits.pool == {}


def test_only_the_policys_failures_are_pooled_and_the_oldest_is_forgotten() -> None:
    revisits = FailedStartRevisits(0.0, capacity=2)
    for seed, status in [(10, "success"), (11, "server_restarted"), (12, "robot_error"),
                         (13, ""), (14, "collision"), (15, "max_steps_exceeded"),
                         (16, "collision")]:  # fmt: skip
        revisits.record(seed, False, status)
    assert list(revisits.pool) == [15, 16]
    assert all(not revisits.next_start()[1] for _ in range(50))  # probability 0: never


def test_revisit_share_follows_the_probability() -> None:
    revisits = FailedStartRevisits(0.25, capacity=1000, max_revisits=1000, seed=0)
    revisits.record(FIRST_SEED, False, "collision")
    share = np.mean([revisits.next_start()[1] for _ in range(4000)])
    assert share == pytest.approx(0.25, abs=0.03)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"probability": 1.5}, "probability"),
        ({"probability": float("nan")}, "probability"),
        ({"probability": 0.5, "capacity": 0}, "capacity"),
        ({"probability": 0.5, "max_revisits": 0}, "max_revisits"),
    ],  # fmt: skip
)
def test_bad_settings_are_refused(kwargs: dict[str, Any], match: str) -> None:
    with pytest.raises(ConfigError, match=match):
        FailedStartRevisits(**kwargs)


@pytest.mark.parametrize(
    ("field", "value"),
    [
        ("revisit_failed", -0.1),
        ("revisit_failed", float("nan")),
        ("revisit_pool", 0),
        ("revisit_max", 0),
    ],  # fmt: skip
)
def test_train_config_checks_the_revisit_fields(field: str, value: float) -> None:
    with pytest.raises(ConfigError, match=f"TrainConfig.{field}"):
        TrainConfig(**{field: value})


def test_workers_get_revisits_only_when_asked() -> None:
    assert revisits_for(TrainConfig(), 0) is None  # off by default
    on = revisits_for(TrainConfig(revisit_failed=0.3, revisit_pool=5, revisit_max=4), 1)
    assert on is not None and (on.probability, on.capacity, on.max_revisits) == (0.3, 5, 4)


class _RecordResets(gym.Wrapper):
    """Keeps the seed, first observation and target of every reset of the wrapped Sim env."""

    def __init__(self, env: gym.Env) -> None:
        super().__init__(env)
        self.resets: list[tuple[int | None, np.ndarray, np.ndarray]] = []

    def reset(self, **kwargs: Any) -> Any:
        obs, info = self.env.reset(**kwargs)
        self.resets.append((kwargs.get("seed"), obs, np.array(self.env.unwrapped.target)))
        return obs, info


def test_worker_reruns_the_scene_of_a_failed_episode() -> None:
    # Three steps cannot reach a target >= 1 m away: every episode fails (max_steps_exceeded).
    def make_env() -> gym.Env:
        return _RecordResets(gym.make("RoboGymRay/ObstacleAvoidanceMir100Sim-v0", max_steps=3))

    revisits = FailedStartRevisits(1.0, max_revisits=2, seed=0)
    worker = RolloutWorker(make_env, SMALL, seed=0, random_steps=100, revisits=revisits)
    try:
        result = worker.collect(18)
        flags = [(e.revisit, e.final_status) for e in result.episodes]
        assert flags == [(r, "max_steps_exceeded") for r in [False, True, True] * 2]
        resets = worker.env.resets
        seeds = [seed for seed, _, _ in resets]
        assert seeds[0] == seeds[1] == seeds[2] != seeds[3] == seeds[4] == seeds[5]
        for a, b in [(0, 1), (0, 2), (3, 4)]:  # a revisit meets the same start and goal
            np.testing.assert_array_equal(resets[a][1], resets[b][1])
            np.testing.assert_array_equal(resets[a][2], resets[b][2])
        assert not np.array_equal(resets[0][2], resets[3][2])
    finally:
        worker.close()
