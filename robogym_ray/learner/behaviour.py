"""The behaviour policy: a CPU copy of the learner's policy plus Gaussian exploration noise.

What Acme calls an actor; named for what it is here, because "actor" already means a Ray actor
(``distributed/``) and the real-robot actor.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import torch

from robogym_ray.learner.networks import Policy


class BehaviourPolicy:
    """Acts with a CPU copy of the policy; each rollout worker has its own ``sigma`` (Ape-X).

    Actions are on the policy's [-1, 1] scale; :func:`to_env_action` maps them to a Box.
    """

    def __init__(
        self,
        obs_dim: int,
        act_dim: int,
        hidden: Sequence[int],
        sigma: float,
        layer_norm: bool = False,
        seed: int | None = None,
    ) -> None:
        self.policy = Policy(obs_dim, act_dim, hidden, layer_norm).requires_grad_(False)
        self.sigma = sigma
        self.act_dim = act_dim
        self.rng = np.random.default_rng(seed)
        self._read_box()

    def set_weights(self, weights: dict[str, np.ndarray]) -> None:
        self.policy.load_state_dict({k: torch.as_tensor(v) for k, v in weights.items()})
        self._read_box()

    def _read_box(self) -> None:
        # The box arrives with the weights only; read once here, not on every step.
        self.center = self.policy.box_center.numpy().astype(np.float64)
        self.half = self.policy.box_half.numpy().astype(np.float64)

    def act(self, obs: np.ndarray, explore: bool) -> np.ndarray:
        """Policy action for one observation, plus N(0, sigma) noise when exploring, clipped."""
        return self.act_batch(np.asarray(obs)[None], explore)[0]

    def act_batch(self, obs: np.ndarray, explore: bool) -> np.ndarray:
        """Actions for a batch of observations (B x obs_dim): one forward pass for all.

        The noise is drawn as one (B x act_dim) block, so a batch of one draws exactly what
        ``act`` draws."""
        with torch.inference_mode():
            action = self.policy(torch.as_tensor(obs, dtype=torch.float32)).numpy()
        if explore and self.sigma > 0:
            # sigma is on the action box's own scale (the whole Box's when there is none).
            action = action + self.sigma * self.half * self.rng.standard_normal(action.shape)
        return np.clip(action, self.center - self.half, self.center + self.half).astype(np.float32)


def to_env_action(action: np.ndarray, low: np.ndarray, high: np.ndarray) -> np.ndarray:
    """Map an action in [-1, 1] affinely onto the Box ``[low, high]``."""
    return low + (action + 1.0) * 0.5 * (high - low)


def from_env_action(action: np.ndarray, low: np.ndarray, high: np.ndarray) -> np.ndarray:
    """The inverse of ``to_env_action``: an action in the Box's units onto [-1, 1] (for
    policies that answer in the env's units, e.g. Stable-Baselines3's ``predict``)."""
    return 2.0 * (np.asarray(action) - low) / (high - low) - 1.0
