"""Evaluator (plain class): the greedy policy on its own env, the paper's supervision instance.

It keeps the final status of the last 100 episodes and reports success / collision / timeout
rates over them, plus returns. Every ``video_every_s`` seconds it films the first episode of a
call, when its env renders ``rgb_array`` frames, for TensorBoard's ``eval/video``.
"""

from __future__ import annotations

import time
from collections import deque
from collections.abc import Mapping

import numpy as np

from robogym_ray.experience.rollout import EnvFactory, box_dims
from robogym_ray.envs.render.video import gif_bytes
from robogym_ray.learner.actor import PolicyActor, to_env_action
from robogym_ray.learner.config import D4PGConfig

TIMEOUT = "max_steps_exceeded"
VIDEO_KEY = "eval_video_gif"
MAX_VIDEO_FRAMES = 120  # a longer episode is subsampled: the GIF stays ~1-2 MB


def status_rates(statuses: list[str]) -> dict[str, float]:
    """success / collision / timeout rates (0..1) over ``statuses``."""
    n = max(1, len(statuses))
    return {
        "success_rate": sum(s == "success" for s in statuses) / n,
        "collision_rate": sum(s == "collision" for s in statuses) / n,
        "timeout_rate": sum(s in (TIMEOUT, "truncated") for s in statuses) / n,
    }


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
    ) -> None:
        self.env = make_env()
        obs_dim, act_dim = box_dims(self.env)
        self.low = self.env.action_space.low.astype(np.float64)
        self.high = self.env.action_space.high.astype(np.float64)
        self.actor = PolicyActor(obs_dim, act_dim, d4pg.policy_hidden, 0.0, d4pg.layer_norm)
        self.seed = seed
        self.episodes = 0
        self.statuses: deque[str] = deque(maxlen=window)
        self.returns: deque[float] = deque(maxlen=window)
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
            obs, _ = self.env.reset(seed=seed)
            self.episodes += 1
            ret, done, info = 0.0, False, {}
            while not done:
                if film and i == 0:
                    frames.append(self.env.render())
                action = self.actor.act(np.asarray(obs, dtype=np.float32), explore=False)
                obs, reward, terminated, truncated, info = self.env.step(
                    to_env_action(action, self.low, self.high)
                )
                ret += float(reward)
                done = terminated or truncated
            status = str(info.get("final_status", "truncated" if truncated else "terminated"))
            self.statuses.append(status)
            self.returns.append(ret)
            rets.append(ret)
            call_statuses.append(status)
        out = {
            "eval_snapshot_success_rate": status_rates(call_statuses)["success_rate"],
            "eval_return": float(np.mean(rets)),
            "eval_return_window": float(np.mean(self.returns)),
            "eval_episodes": float(self.episodes),
            "weights_version": float(version),
            **{f"eval_{k}": v for k, v in status_rates(list(self.statuses)).items()},
        }
        if frames:
            frames.append(self.env.render())  # the end state, where the episode stopped
            stride = -(-len(frames) // MAX_VIDEO_FRAMES)
            fps = self.env.metadata.get("render_fps", 10) / stride
            out[VIDEO_KEY] = gif_bytes(frames[::stride] + frames[-1:], fps)
            self._next_video = time.monotonic() + self.video_every_s
        return out

    def close(self) -> None:
        self.env.close()
