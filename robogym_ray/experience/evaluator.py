"""Evaluator (plain class): the greedy policy on its own env, the paper's supervision instance.

It keeps the final status of the last 100 episodes and reports success / collision / timeout
rates over them, plus returns. A task with command windows (the deploy reach, whose episodes end
only by time) is measured by its window-end errors instead: their medians over the same
episodes. Every ``video_every_s`` seconds it films the first episode of a call, when its env
renders ``rgb_array`` frames, for TensorBoard's ``eval/video``.
"""

from __future__ import annotations

import time
from collections import deque
from collections.abc import Mapping

import numpy as np

from robogym_ray.envs.outcomes import rates, window_medians
from robogym_ray.envs.render.video import gif_bytes
from robogym_ray.experience.episodes import greedy_episode
from robogym_ray.experience.rollout import EnvFactory, box_dims
from robogym_ray.learner.behaviour import BehaviourPolicy
from robogym_ray.learner.config import D4PGConfig

VIDEO_KEY = "eval_video_gif"
MAX_VIDEO_FRAMES = 120  # a longer episode is subsampled: the GIF stays ~1-2 MB


class Evaluator:
    """Runs deterministic (noise-free) episodes with the latest weights."""

    def __init__(
        self,
        make_env: EnvFactory,
        d4pg: D4PGConfig,
        *,
        seed: int = 10_000,
        window: int = 100,
        video_every_s: float = 0.0,
        first_episode: int = 0,
    ) -> None:
        """``first_episode``: episodes a dead predecessor played; a replacement goes on from
        there (its count and seeds), with an empty window."""
        self.env = make_env()
        obs_dim, act_dim = box_dims(self.env)
        self.actor = BehaviourPolicy(obs_dim, act_dim, d4pg.policy_hidden, 0.0, d4pg.layer_norm)
        self.seed = seed
        self.episodes = first_episode
        self.statuses: deque[str] = deque(maxlen=window)
        self.returns: deque[float] = deque(maxlen=window)
        self.windows: deque[list[list[float]]] = deque(maxlen=window)
        self.video_every_s = video_every_s if self.env.render_mode == "rgb_array" else 0.0
        self._next_video = 0.0  # the first call films

    def evaluate(
        self,
        weights: Mapping[str, np.ndarray],
        version: int,
        episodes: int = 1,
        seed_base: int | None = None,
    ) -> dict:
        """Run ``episodes`` greedy episodes; returns rates over the window and this call's own.

        Episodes are seeded ``seed, seed + 1, ...`` across calls (every call sees new ones);
        with ``seed_base``, episode ``i`` of the call uses ``seed_base + i``, so calls with
        different weights are scored on the same episodes (snapshot selection). A filmed call
        adds the first episode as an animated GIF under ``VIDEO_KEY``.
        """
        self.actor.set_weights(dict(weights))
        rets, call_statuses, frames = [], [], []
        film = self.video_every_s > 0 and time.monotonic() >= self._next_video
        for i in range(episodes):
            seed = self.seed + self.episodes if seed_base is None else seed_base + i
            episode = greedy_episode(self.env, self._act, seed, film=film and i == 0)
            self.episodes += 1
            frames = frames or episode.frames
            self.statuses.append(episode.final_status)
            self.returns.append(episode.ret)
            if episode.window_errors:
                self.windows.append(episode.window_errors)
            rets.append(episode.ret)
            call_statuses.append(episode.final_status)
        # medians over every window of the kept episodes, as `evaluate` scores them
        windows = window_medians(w for episode in self.windows for w in episode)
        out = {
            "eval_snapshot_success_rate": rates(call_statuses)["success_rate"],
            "eval_return": float(np.mean(rets)),
            "eval_return_window": float(np.mean(self.returns)),
            "eval_episodes": float(self.episodes),
            "weights_version": float(version),
            **{f"eval_{k}": v for k, v in rates(self.statuses).items()},
            **{f"eval_{k}": v for k, v in windows.items()},
        }
        if frames:
            stride = -(-len(frames) // MAX_VIDEO_FRAMES)
            fps = self.env.metadata.get("render_fps", 10) / stride
            out[VIDEO_KEY] = gif_bytes(frames[::stride] + frames[-1:], fps)
            self._next_video = time.monotonic() + self.video_every_s
        return out

    def _act(self, obs: np.ndarray) -> np.ndarray:
        return self.actor.act(obs, explore=False)

    def close(self) -> None:
        self.env.close()
