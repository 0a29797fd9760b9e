"""``ActionRepeat`` (``envs/repeat.py``) on the deploy reach's real PyBullet servo: a decision
held for k steps is those k steps of the env, their rewards summed, the episode's end and its
command windows' errors kept. A training with it: tests/distributed/test_action_repeat_training.py.
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

from robogym_ray.envs.repeat import ActionRepeat, repeating
from robogym_ray.errors import ConfigError
from robogym_ray.experience.rollout import make_gym_env

DEPLOY = "RoboGymRay/IsaacDeployReachUR10eSim-v0"
REPEAT = 4


def test_a_held_decision_is_the_envs_steps_summed() -> None:
    plain, held = gym.make(DEPLOY), ActionRepeat(gym.make(DEPLOY), REPEAT)
    try:
        obs, _ = plain.reset(seed=5)
        held_obs, _ = held.reset(seed=5)
        np.testing.assert_array_equal(obs, held_obs)
        rng = np.random.default_rng(0)
        windows, decisions = 0, 0
        while True:
            action = rng.uniform(-1, 1, 6).astype(np.float32)
            rewards, infos = [], {}
            for _ in range(REPEAT):
                obs, reward, terminated, truncated, info = plain.step(action)
                rewards.append(reward)
                infos.update(info)
                if terminated or truncated:
                    break
            held_obs, reward, held_term, held_trunc, held_info = held.step(action)
            decisions += 1
            np.testing.assert_array_equal(held_obs, obs)
            assert reward == pytest.approx(sum(rewards), rel=1e-12, abs=1e-15)
            assert (held_term, held_trunc) == (terminated, truncated)
            # A window ending on any step inside the decision still reports its errors.
            assert held_info.keys() == infos.keys()
            windows += "window_position_error" in held_info
            if terminated or truncated:
                break
        # 720 steps of 12 s, a new command every 240: 180 decisions, three window ends.
        assert (decisions, windows, held_trunc) == (720 // REPEAT, 3, True)
    finally:
        plain.close()
        held.close()


def test_an_episode_ending_inside_a_decision_ends_it_there() -> None:
    # 7 does not divide the 720 steps: the last decision is cut after its 6th step.
    env = ActionRepeat(gym.make(DEPLOY), 7)
    try:
        env.reset(seed=1)
        for _ in range(720 // 7):
            assert not env.step(np.zeros(6, np.float32))[3]
        truncated = env.step(np.zeros(6, np.float32))[3]
        assert truncated and env.unwrapped.elapsed_steps == 720
    finally:
        env.close()


@pytest.mark.parametrize("repeat", [0, -2, 1.5, True, "4"])
def test_a_repeat_that_is_not_a_count_is_refused(repeat: object) -> None:
    env = gym.make("Pendulum-v1")
    with pytest.raises(ConfigError, match="action repeat must be an int >= 1"):
        ActionRepeat(env, repeat)  # type: ignore[arg-type]
    env.close()


def test_repeat_one_is_the_envs_own_factory() -> None:
    factory = make_gym_env("Pendulum-v1")
    assert repeating(factory, 1) is factory
    env = repeating(factory, 3)()
    assert isinstance(env, ActionRepeat) and env.repeat == 3
    env.close()
