"""Hindsight relabelling (``experience/relabel.py``): a relabelled transition is what the env
itself gives when the episode is played again under that command, window and bootstrap
included; goals come from the episode's own later poses; the UR10 reach on Isaac Lab's reward
scores any command as it scores its own; tasks that cannot be relabelled are refused."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import pytest

import robogym_ray
from robogym_ray.errors import ConfigError
from robogym_ray.experience.relabel import HindsightRelabeller, goal_task
from robogym_ray.experience.rollout import RolloutWorker
from robogym_ray.learner.config import D4PGConfig
from robogym_ray.learner.nstep import NStepAccumulator, Transition

LENGTH = 12


class PointReach(gym.Env[np.ndarray, np.ndarray]):
    """A point in the plane driven to a command: obs = (position, command); reward = minus the
    distance after the step, minus an effort term that no command changes; ends by time."""

    observation_space = gym.spaces.Box(-10.0, 10.0, (4,), np.float32)
    action_space = gym.spaces.Box(-1.0, 1.0, (2,), np.float32)
    goal_slice = slice(2, 4)
    reward_info_keys = ("effort",)
    ends_on_goal = False

    def reset(self, *, seed: int | None = None, options: Any = None) -> tuple[np.ndarray, dict]:
        super().reset(seed=seed)
        self.position = self.np_random.uniform(-1.0, 1.0, 2)
        given = (options or {}).get("command")
        self.command = self.np_random.uniform(-1, 1, 2) if given is None else np.asarray(given)
        self.t = 0
        return self._obs(), {}

    def _obs(self) -> np.ndarray:
        return np.concatenate([self.position, self.command]).astype(np.float32)

    def compute_reward(self, achieved_goal: Any, desired_goal: Any, info: Any) -> np.ndarray:
        gap = np.atleast_2d(achieved_goal) - np.atleast_2d(desired_goal)
        return -np.linalg.norm(gap, axis=1) + np.asarray(info["effort"])

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict]:
        self.position = self.position + 0.2 * np.asarray(action, np.float64)
        self.t += 1
        info = {"achieved_goal": self.position.copy(), "effort": -0.01 * float(action @ action)}
        reward = float(self.compute_reward(self.position, self.command, info)[0])
        return self._obs(), reward, False, self.t >= LENGTH, info


def play(env: PointReach, seed: int, actions: np.ndarray, command: Any = None) -> list[tuple]:
    """The episode from reset seed ``seed`` under ``actions``: (obs, action, reward, next_obs,
    terminated, truncated, info) per step."""
    obs, _ = env.reset(seed=seed, options={"command": command})
    steps = []
    for action in actions:
        next_obs, reward, terminated, truncated, info = env.step(action)
        steps.append((obs, action, reward, next_obs, terminated, truncated, info))
        obs = next_obs
    return steps


def accumulated(steps: list[tuple], n_step: int, discount: float) -> list[Transition]:
    acc, out = NStepAccumulator(n_step, discount), []
    for obs, action, reward, next_obs, terminated, truncated, _ in steps:
        out += acc.push(obs, action, reward, next_obs, terminated, truncated)
    return out


@pytest.mark.parametrize("n_step", [1, 3, 5])
def test_a_relabelled_episode_is_the_episode_played_under_that_command(n_step: int) -> None:
    env, discount = PointReach(), 0.9
    actions = np.random.default_rng(0).uniform(-1, 1, (LENGTH, 2)).astype(np.float32)
    steps = play(env, 7, actions)
    relabeller = HindsightRelabeller(goal_task(env), 0, n_step, discount, np.random.default_rng())
    for obs, action, _, next_obs, _, _, info in steps:
        relabeller.record(obs, action, next_obs, info)
    command = steps[8][6]["achieved_goal"]  # a pose the episode reached
    starts = np.arange(LENGTH)
    relabelled = relabeller.relabel(
        relabeller.steps, starts, np.tile(command, (LENGTH, 1)), terminated=False
    )
    # The same start and actions, the env given that command: its own n-step transitions.
    again = accumulated(play(env, 7, actions, command), n_step, discount)
    assert len(relabelled) == len(again) == LENGTH
    for ours, env_s in zip(relabelled, again, strict=True):
        np.testing.assert_allclose(ours.obs, env_s.obs, atol=1e-6)
        np.testing.assert_allclose(ours.next_obs, env_s.next_obs, atol=1e-6)
        np.testing.assert_array_equal(ours.action, env_s.action)
        assert ours.reward == pytest.approx(env_s.reward, abs=1e-6)
        assert ours.discount == pytest.approx(env_s.discount)
    # The step that reached the command: its reward is the effort alone.
    if n_step == 1:
        assert relabelled[8].reward == pytest.approx(steps[8][6]["effort"])


def test_the_command_in_force_gives_the_accumulators_transitions() -> None:
    env = PointReach()
    actions = np.random.default_rng(1).uniform(-1, 1, (LENGTH, 2)).astype(np.float32)
    steps = play(env, 3, actions)
    relabeller = HindsightRelabeller(goal_task(env), 0, 4, 0.95, np.random.default_rng())
    for obs, action, _, next_obs, _, _, info in steps:
        relabeller.record(obs, action, next_obs, info)
    own = np.tile(steps[0][0][PointReach.goal_slice], (LENGTH, 1))
    for terminated in (False, True):
        ours = relabeller.relabel(relabeller.steps, np.arange(LENGTH), own, terminated)
        flags = [(*s[:4], terminated and i == LENGTH - 1, not terminated and i == LENGTH - 1, {})
                 for i, s in enumerate(steps)]  # fmt: skip
        theirs = accumulated(flags, 4, 0.95)
        assert [t.reward for t in ours] == pytest.approx([t.reward for t in theirs], abs=1e-6)
        assert [t.discount for t in ours] == pytest.approx([t.discount for t in theirs])
        assert terminated == (ours[-1].discount == 0.0)


def test_each_copy_takes_a_pose_the_episode_reached_then_or_later() -> None:
    env, copies = PointReach(), 4
    steps = play(env, 5, np.random.default_rng(2).uniform(-1, 1, (LENGTH, 2)))
    relabeller = HindsightRelabeller(goal_task(env), copies, 2, 0.9, np.random.default_rng(3))
    for obs, action, _, next_obs, _, _, info in steps:
        relabeller.record(obs, action, next_obs, info)
    out = relabeller.finish(terminated=False)
    assert len(out) == copies * LENGTH and len(relabeller.steps) == 0  # a fresh record
    reached = [s[6]["achieved_goal"] for s in steps]
    starts = [s[0][:2] for s in steps]
    for transition in out:
        (t,) = [i for i, p in enumerate(starts) if np.allclose(p, transition.obs[:2])]
        goal = transition.obs[2:]
        assert any(np.allclose(goal, reached[later], atol=1e-6) for later in range(t, LENGTH))
        np.testing.assert_allclose(transition.next_obs[2:], goal)


def test_a_worker_stores_the_copies_beside_its_own_transitions() -> None:
    worker = RolloutWorker(PointReach, D4PGConfig(n_step=3), seed=0, num_envs=2,
                           random_steps=10**6, relabel_goals=2)  # fmt: skip
    result = worker.collect(5 * LENGTH)  # 30 steps on each env: two episodes end on each
    finished = sum(ep.length for ep in result.episodes)
    assert finished > 0 and result.relabelled == 2 * finished
    assert result.transitions == len(result.batch["reward"])
    assert result.transitions - result.relabelled <= result.steps


class Terminating(PointReach):
    ends_on_goal = True


def test_tasks_that_cannot_be_relabelled_are_refused(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="Pendulum-v1 has no command to relabel"):
        goal_task(gym.make("Pendulum-v1"), "Pendulum-v1")
    with pytest.raises(ConfigError, match="ends episodes on reaching its command"):
        goal_task(Terminating())
    with pytest.raises(ConfigError, match="has no command to relabel"):
        RolloutWorker(lambda: gym.make("Pendulum-v1"), D4PGConfig(), relabel_goals=1)
    with pytest.raises(ConfigError, match=r"relabel_goals=2: Pendulum-v1 has no command"):
        robogym_ray.train(task="pendulum", relabel_goals=2, logdir=str(tmp_path))
    with pytest.raises(ConfigError, match="relabel_goals"):
        robogym_ray.train(task="pendulum", relabel_goals=-1, logdir=str(tmp_path))
    assert list(tmp_path.iterdir()) == []  # refused before anything was written


@pytest.mark.parametrize(
    ("env_id", "window"),
    [("RoboGymRay/IsaacReachIsaacRewardUR10Sim-v0", 120),
     ("RoboGymRay/IsaacReachRotationTanhUR10Sim-v0", 120),
     ("RoboGymRay/IsaacReachFineTanhUR10Sim-v0", 120),
     ("RoboGymRay/IsaacDeployReachUR10eSim-v0", 240)],
)  # fmt: skip
def test_isaac_labs_reach_tasks_score_any_command_as_their_own(env_id: str, window: int) -> None:
    """Real PyBullet, random steps past the first new command: ``compute_reward`` of the pose
    reached and the command the step's observation showed is the env's reward."""
    env = gym.make(env_id)
    try:
        task = goal_task(env, env_id)
        obs, _ = env.reset(seed=4)
        rng = np.random.default_rng(4)
        commands = set()
        for _ in range(window + 10):
            action = rng.uniform(-0.3, 0.3, 6).astype(np.float32)
            next_obs, reward, _, _, info = env.step(action)
            command = obs[task.goal_slice]
            commands.add(tuple(command))
            ours = task.compute_reward(info["achieved_goal"], command, {"effort": info["effort"]})
            assert float(ours[0]) == pytest.approx(reward, abs=1e-6)
            obs = next_obs
        assert len(commands) == 2  # the step after the new command scored it too
    finally:
        env.close()
