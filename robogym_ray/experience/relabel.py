"""Hindsight relabelling of a task's command: the "future" strategy of hindsight experience
replay (Andrychowicz et al., 2017), applied to whole n-step windows.

A reaching task's reward is a function of the pose the arm reached and the command it was
given, and the command does not change what the arm does. So every step of an episode is also
a step of the same episode under another command: this module stores an episode's steps with
the pose each one reached, and when the episode ends writes ``copies`` more transitions per
step, each under a command the same episode reached at that step or later. The command's slot
in the observation (``goal_slice``) is rewritten in both ends of the transition and every
reward of its n-step window is recomputed by the env's own ``compute_reward``; the window,
its discount and its bootstrap are ``NStepAccumulator``'s (``tests/test_relabel.py`` checks
that relabelling with the command in force gives the accumulator's transitions).

A task opts in by having (on ``env.unwrapped``), as Gymnasium-Robotics' ``GoalEnv`` has:

* ``goal_slice``: where the command sits in the observation;
* ``info["achieved_goal"]`` after every step: the pose reached, in the slot's layout;
* ``compute_reward(achieved_goal, desired_goal, info)``: the step's reward for a command,
  vectorised over a leading axis, ``info`` a dict of arrays of the keys ``reward_info_keys``
  names (what the reward needs besides the two poses: an effort term, say);
* ``ends_on_goal = False``: no end of an episode depends on the command, so a relabelled
  episode ends where the real one did (a task that terminates on success is refused).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import gymnasium as gym
import numpy as np

from robogym_ray.errors import ConfigError
from robogym_ray.learner.nstep import Transition

GOAL_TASK_PARTS = ("goal_slice", "compute_reward", "reward_info_keys", "ends_on_goal")


def goal_task(env: gym.Env, env_id: str = "") -> Any:
    """``env.unwrapped`` when it can be relabelled (see the module docstring); a ConfigError
    saying what it lacks otherwise."""
    task = env.unwrapped
    name = env_id or type(task).__name__
    missing = [part for part in GOAL_TASK_PARTS if not hasattr(task, part)]
    if missing:
        raise ConfigError(
            f"{name} has no command to relabel (it lacks {', '.join(missing)}): relabelling "
            "needs a task whose reward is a function of the pose reached and the command, "
            "such as isaac-reach-ur10-isaac-reward"
        )
    if task.ends_on_goal:
        raise ConfigError(
            f"{name} ends episodes on reaching its command: a relabelled episode would end "
            "elsewhere, so relabelling needs a task that ends by time only"
        )
    return task


@dataclass
class EpisodeSteps:
    """The running episode's steps as the relabeller needs them."""

    obs: list[np.ndarray] = field(default_factory=list)
    action: list[np.ndarray] = field(default_factory=list)
    next_obs: list[np.ndarray] = field(default_factory=list)
    achieved: list[np.ndarray] = field(default_factory=list)
    info: list[list[float]] = field(default_factory=list)

    def __len__(self) -> int:
        return len(self.obs)


class HindsightRelabeller:
    """One env's episode record and its relabelled transitions.

    Args:
        task: the env's ``goal_task``.
        copies: relabelled transitions per step (HER's k; 4 in the paper's "future" runs).
        n_step, discount: the learner's, as the worker's ``NStepAccumulator`` has them.
        rng: draws the future step each copy takes its command from.
    """

    def __init__(
        self, task: Any, copies: int, n_step: int, discount: float, rng: np.random.Generator
    ) -> None:
        if copies < 0:
            raise ConfigError(f"relabel_goals={copies}; expected >= 0")
        self.task, self.copies, self.n_step, self.discount = task, copies, n_step, discount
        self.slot: slice = task.goal_slice
        self.keys: tuple[str, ...] = tuple(task.reward_info_keys)
        self.rng = rng
        self.steps = EpisodeSteps()

    def record(
        self, obs: np.ndarray, action: np.ndarray, next_obs: np.ndarray, info: dict[str, Any]
    ) -> None:
        """One step of the running episode (after the env's ``step``)."""
        s = self.steps
        s.obs.append(np.asarray(obs, dtype=np.float32))
        s.action.append(np.asarray(action, dtype=np.float32))
        s.next_obs.append(np.asarray(next_obs, dtype=np.float32))
        s.achieved.append(np.asarray(info["achieved_goal"], dtype=np.float64))
        s.info.append([float(info[key]) for key in self.keys])

    def drop(self) -> int:
        """Forget the running episode (it was cut by a crash or abandoned); its step count."""
        dropped = len(self.steps)
        self.steps = EpisodeSteps()
        return dropped

    def finish(self, terminated: bool) -> list[Transition]:
        """The relabelled transitions of the episode that just ended (``terminated``: by the
        env, not the time limit, as ``NStepAccumulator.push`` takes it), and a fresh record."""
        steps, self.steps = self.steps, EpisodeSteps()
        length = len(steps)
        if length == 0 or self.copies == 0:
            return []
        starts = np.repeat(np.arange(length), self.copies)
        # "future": the pose reached at a uniformly drawn step from t to the episode's end.
        future = starts + (self.rng.random(starts.size) * (length - starts)).astype(np.int64)
        reached = np.stack(steps.achieved)
        return self.relabel(steps, starts, reached[future], terminated, reached=reached)

    def relabel(
        self,
        steps: EpisodeSteps,
        starts: np.ndarray,
        goals: np.ndarray,
        terminated: bool,
        reached: np.ndarray | None = None,
    ) -> list[Transition]:
        """The n-step transitions starting at ``starts`` under the commands ``goals`` (one
        row each, in the observation slot's layout); ``reached``: ``steps.achieved`` stacked,
        if the caller has it already."""
        length, n = len(steps), self.n_step
        reached = np.stack(steps.achieved) if reached is None else reached
        offsets = np.arange(n)
        window = starts[:, None] + offsets[None, :]  # (N, n) step indices
        inside = window < length
        clipped = np.minimum(window, length - 1)
        achieved = reached[clipped.ravel()]
        desired = np.repeat(goals, n, axis=0)
        columns = np.asarray(steps.info, dtype=np.float64).reshape(length, len(self.keys))
        info = {k: columns[clipped.ravel(), i] for i, k in enumerate(self.keys)}
        rewards = np.asarray(self.task.compute_reward(achieved, desired, info), np.float64)
        rewards = rewards.reshape(window.shape) * inside
        powers = self.discount ** offsets.astype(np.float64)
        returns = rewards @ powers
        span = inside.sum(axis=1)  # each window's length m (shorter at the episode's end)
        discounts = self.discount ** span.astype(np.float64)
        if terminated:  # a window that reaches a termination does not bootstrap
            discounts[starts + span >= length] = 0.0
        out = []
        for start, m, goal, ret, disc in zip(starts, span, goals, returns, discounts, strict=True):
            obs = steps.obs[start].copy()
            obs[self.slot] = goal
            last = steps.next_obs[start + m - 1].copy()
            last[self.slot] = goal
            out.append(Transition(obs, steps.action[start], float(ret), float(disc), last))
        return out
