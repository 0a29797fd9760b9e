"""n-step transition accumulator used by actors (rollout workers) before inserting into replay.

Convention (as in Acme's adders): a transition starting at step t carries
``R = sum_{k<m} gamma^k r_{t+k}`` and the bootstrap discount ``gamma^m`` applied to
``Z(next_obs)``, where ``m <= n`` is the window length (shortened at the end of an episode).
A termination inside the window sets the discount to 0; a time-limit truncation keeps
``gamma^m`` so the learner bootstraps from the last observation.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from robogym_ray.errors import ConfigError


@dataclass(frozen=True)
class Transition:
    """One n-step transition as stored in replay (actions on the policy's [-1, 1] scale)."""

    obs: np.ndarray
    action: np.ndarray
    reward: float
    discount: float
    next_obs: np.ndarray


def stack_transitions(transitions: Sequence[Transition]) -> dict[str, np.ndarray]:
    """Batch transitions into float32 arrays keyed like the replay's storage."""
    return {
        "obs": np.stack([t.obs for t in transitions]).astype(np.float32),
        "action": np.stack([t.action for t in transitions]).astype(np.float32),
        "reward": np.array([t.reward for t in transitions], dtype=np.float32),
        "discount": np.array([t.discount for t in transitions], dtype=np.float32),
        "next_obs": np.stack([t.next_obs for t in transitions]).astype(np.float32),
    }


class NStepAccumulator:
    """Turns a stream of one-step experience into n-step transitions.

    Call :meth:`push` after every env step; it returns the transitions that became complete.
    Call :meth:`drop` when an episode is abandoned (e.g. the robot server crashed mid-episode):
    the unfinished window is discarded so that no transition spans the crash.
    """

    def __init__(self, n_step: int, discount: float) -> None:
        if n_step < 1:
            raise ConfigError(f"n_step={n_step}; expected >= 1")
        if not 0.0 < discount <= 1.0:
            raise ConfigError(f"discount={discount}; expected in (0, 1]")
        self.n_step = n_step
        self.discount = discount
        # (obs, action, reward) of the steps whose transitions are not emitted yet.
        self._window: deque[tuple[np.ndarray, np.ndarray, float]] = deque()

    def __len__(self) -> int:
        return len(self._window)

    def push(
        self,
        obs: np.ndarray,
        action: np.ndarray,
        reward: float,
        next_obs: np.ndarray,
        terminated: bool,
        truncated: bool,
    ) -> list[Transition]:
        """Add one env step; return the n-step transitions completed by it (oldest first)."""
        self._window.append((np.asarray(obs), np.asarray(action), float(reward)))
        if terminated or truncated:
            # Episode over: flush every pending start with a shortened window.
            out = [self._emit(next_obs, terminated) for _ in range(len(self._window))]
            return out
        if len(self._window) == self.n_step:
            return [self._emit(next_obs, terminated=False)]
        return []

    def drop(self) -> int:
        """Discard the unfinished window (no transitions emitted); return how many steps."""
        dropped = len(self._window)
        self._window.clear()
        return dropped

    reset = drop

    def _emit(self, next_obs: np.ndarray, terminated: bool) -> Transition:
        """Pop the oldest pending step and build its transition over the current window."""
        ret, scale = 0.0, 1.0
        for _, _, r in self._window:
            ret += scale * r
            scale *= self.discount
        obs, action, _ = self._window.popleft()
        # ``scale`` is now gamma**m for the window length m.
        return Transition(obs, action, ret, 0.0 if terminated else scale, np.asarray(next_obs))
