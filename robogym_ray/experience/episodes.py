"""The one greedy-episode loop: the evaluator, ``robogym-ray evaluate`` and the single-process
trainer run a policy through an episode with it, so they score episodes the same way."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from robogym_ray.envs.outcomes import WINDOW_KEYS, final_status
from robogym_ray.learner.behaviour import to_env_action

Policy = Callable[[np.ndarray], np.ndarray]
"""Observation -> action on the policy's [-1, 1] scale (clipped, then mapped to the Box). A
policy with state across steps (Isaac ROS's action filter) has a ``reset()``, called before
each episode."""


@dataclass
class GreedyEpisode:
    seed: int | None
    final_status: str
    ret: float
    length: int
    target: list[float] | None
    """The task's target after reset (MiR100: x, y, yaw; UR: x, y, z), if it has one."""
    obstacles: list[list[float]] | None = None
    """With ``track``: the cubes the reset placed (``placed_obstacles()``), if any."""
    path: list[list[float]] | None = None
    """With ``track``: the robot's position (``position()``) after reset and each step."""
    frames: list[np.ndarray] = field(default_factory=list)
    """With ``film``: ``env.render()`` after reset and each step (the env renders rgb_array)."""
    position_error: float | None = None
    """The end effector's distance to its target at the end (m), for tasks that report it."""
    rotation_error: float | None = None
    """Its rotation error at the end (rad), for tasks whose target has an orientation."""
    window_errors: list[list[float]] | None = None
    """Tasks with a new command every few seconds (the deploy reach): the (position, rotation)
    errors at the end of each command window, the task's own measure."""


ERROR_KEYS = {"position_error": ("dist_coord", "distance"), "rotation_error": ("dist_rot",)}
"""Where tasks put their final errors in ``info``: the arm tasks of robo-gym 2.1.0 and the UR
positioning task name the distance differently."""


def greedy_episode(
    env: Any,
    policy: Policy,
    seed: int | None,
    *,
    film: bool = False,
    track: bool = False,
) -> GreedyEpisode:
    """Run one episode of ``policy`` on ``env`` from ``env.reset(seed=seed)``, keeping what the
    task reports mid-episode (a command window's errors) as well as at its end."""
    low = env.action_space.low.astype(np.float64)
    high = env.action_space.high.astype(np.float64)
    reset = getattr(policy, "reset", None)
    if reset is not None:
        reset()
    obs, _ = env.reset(seed=seed)
    task = env.unwrapped
    target = getattr(task, "target", None)
    placed = getattr(task, "placed_obstacles", lambda: None)() if track else None
    episode = GreedyEpisode(
        seed, "", 0.0, 0,
        None if target is None else [float(v) for v in np.ravel(target)],
        None if placed is None else np.round(placed, 4).tolist(),
        [_where(task)] if track else None,
    )  # fmt: skip
    if film:
        episode.frames.append(env.render())
    done, truncated, info = False, False, {}
    while not done:
        action = np.clip(policy(np.asarray(obs, dtype=np.float32)), -1.0, 1.0)
        obs, reward, terminated, truncated, info = env.step(to_env_action(action, low, high))
        if WINDOW_KEYS[0] in info:
            window = [round(float(info[k]), 5) for k in WINDOW_KEYS]
            episode.window_errors = [*(episode.window_errors or []), window]
        episode.ret += float(reward)
        episode.length += 1
        done = terminated or truncated
        if film:
            episode.frames.append(env.render())
        if episode.path is not None:
            episode.path.append(_where(task))
    episode.final_status = final_status(info, truncated)
    for attr, keys in ERROR_KEYS.items():
        found = next((info[k] for k in keys if k in info), None)
        setattr(episode, attr, None if found is None else round(float(found), 5))
    return episode


def _where(task: Any) -> list[float]:
    position = task.position() if hasattr(task, "position") else None
    return [] if position is None else [round(float(v), 4) for v in position]
