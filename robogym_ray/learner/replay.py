"""Proportional prioritized replay (Schaul et al. 2016; Ape-X) with vectorized segment trees.

All tree operations work on whole batches: updates propagate level by level with NumPy fancy
indexing, and sampling descends the tree for every sample at once (``log2(capacity)`` vector
steps per batch, no Python loop per sample).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from robogym_ray.errors import ConfigError

FIELDS = ("obs", "action", "reward", "discount", "next_obs")


class SegmentTree:
    """Complete binary tree over ``capacity`` leaves (rounded up to a power of two).

    Node ``i`` has children ``2i`` and ``2i+1``; leaves live at ``[size, 2 * size)``; node 1 is
    the root. ``op`` is ``np.add`` (sum tree) or ``np.minimum`` (min tree).
    """

    def __init__(self, capacity: int, op: np.ufunc, neutral: float) -> None:
        self.size = 1 << max(0, int(capacity - 1).bit_length())
        self.depth = self.size.bit_length() - 1
        self.op = op
        self.neutral = neutral
        self.nodes = np.full(2 * self.size, neutral, dtype=np.float64)

    def update(self, indices: np.ndarray, values: np.ndarray) -> None:
        """Set leaves ``indices`` to ``values`` (last write wins on duplicates) and re-reduce."""
        idx = np.asarray(indices, dtype=np.int64) + self.size
        self.nodes[idx] = values
        for _ in range(self.depth):
            # Children are final before their parents are written, so duplicate parents all get
            # the same value: no np.unique (a sort per level) needed.
            idx = idx >> 1
            self.nodes[idx] = self.op(self.nodes[2 * idx], self.nodes[2 * idx + 1])

    def leaves(self, indices: np.ndarray) -> np.ndarray:
        return self.nodes[np.asarray(indices, dtype=np.int64) + self.size]

    @property
    def root(self) -> float:
        return float(self.nodes[1])


class SumTree(SegmentTree):
    def __init__(self, capacity: int) -> None:
        super().__init__(capacity, np.add, 0.0)

    def find_prefix(self, mass: np.ndarray) -> np.ndarray:
        """Leaf index ``i`` per query with ``sum(p[:i]) <= mass < sum(p[:i+1])``, vectorized."""
        mass = np.array(mass, dtype=np.float64)
        idx = np.ones(mass.shape, dtype=np.int64)
        for _ in range(self.depth):
            left = self.nodes[2 * idx]
            go_right = mass >= left
            mass = np.where(go_right, mass - left, mass)
            idx = 2 * idx + go_right
        return idx - self.size


class MinTree(SegmentTree):
    def __init__(self, capacity: int) -> None:
        super().__init__(capacity, np.minimum, np.inf)


class PrioritizedReplay:
    """Fixed-capacity FIFO ring buffer of n-step transitions with proportional priorities.

    Priorities ``p`` are stored as ``p**alpha`` in a sum tree (sampling) and a min tree (the
    largest importance weight, for normalisation). New data without an explicit priority gets
    the running maximum so that it is sampled soon (the Acme issue #205 pitfall).
    """

    def __init__(
        self,
        capacity: int,
        obs_dim: int,
        act_dim: int,
        alpha: float = 0.6,
        eps: float = 1e-6,
        seed: int | None = None,
    ) -> None:
        if capacity < 1:
            raise ConfigError(f"replay capacity={capacity}; expected >= 1")
        self.capacity, self.alpha, self.eps = capacity, alpha, eps
        self.storage: dict[str, np.ndarray] = {
            "obs": np.zeros((capacity, obs_dim), np.float32),
            "action": np.zeros((capacity, act_dim), np.float32),
            "reward": np.zeros(capacity, np.float32),
            "discount": np.zeros(capacity, np.float32),
            "next_obs": np.zeros((capacity, obs_dim), np.float32),
        }
        self.sum_tree, self.min_tree = SumTree(capacity), MinTree(capacity)
        self.max_priority = 1.0
        self.cursor = 0  # next slot to write; the oldest transition once full
        self.size = 0
        self.total_added = 0
        self.rng = np.random.default_rng(seed)

    def __len__(self) -> int:
        return self.size

    def add(self, batch: dict[str, np.ndarray], priorities: np.ndarray | None = None) -> np.ndarray:
        """Insert a batch (keys :data:`FIELDS`), overwriting the oldest slots once full.

        Returns:
            The slot indices written.
        """
        count = len(batch["reward"])
        if count > self.capacity:  # only the newest ``capacity`` survive FIFO anyway
            batch = {k: np.asarray(v)[-self.capacity :] for k, v in batch.items()}
            priorities = None if priorities is None else np.asarray(priorities)[-self.capacity :]
            count = self.capacity
        idx = (self.cursor + np.arange(count)) % self.capacity
        for key in FIELDS:
            self.storage[key][idx] = batch[key]
        if priorities is None:
            priorities = np.full(count, self.max_priority)
        self._set_priorities(idx, np.asarray(priorities, dtype=np.float64))
        self.cursor = int((self.cursor + count) % self.capacity)
        self.size = min(self.size + count, self.capacity)
        self.total_added += count
        return idx

    def sample(
        self, batch_size: int, beta: float
    ) -> tuple[dict[str, np.ndarray], np.ndarray, np.ndarray]:
        """Draw ``batch_size`` indices with P(i) = p_i^alpha / sum p^alpha (stratified).

        Returns:
            (batch, indices, importance weights ``(N P(i))^-beta / max_j w_j``).
        """
        if self.size == 0:
            raise ConfigError("cannot sample from an empty replay")
        total = self.sum_tree.root
        # One uniform draw per equal-mass stratum lowers variance versus i.i.d. draws.
        mass = (np.arange(batch_size) + self.rng.random(batch_size)) * (total / batch_size)
        idx = self.sum_tree.find_prefix(np.minimum(mass, np.nextafter(total, 0)))
        # Float round-off can walk into an empty leaf past the filled region; clamp back.
        idx = np.minimum(idx, self.size - 1)
        probs = self.sum_tree.leaves(idx) / total
        min_prob = self.min_tree.root / total
        weights = (probs / min_prob) ** (-beta)  # == (N P)^-b / (N P_min)^-b
        batch = {key: self.storage[key][idx] for key in FIELDS}
        return batch, idx, weights.astype(np.float32)

    def update_priorities(self, indices: np.ndarray, priorities: np.ndarray) -> None:
        """Write back learner-computed priorities (e.g. per-sample loss) for sampled slots."""
        self._set_priorities(np.asarray(indices), np.asarray(priorities, dtype=np.float64))

    def _set_priorities(self, idx: np.ndarray, priorities: np.ndarray) -> None:
        priorities = np.abs(priorities) + self.eps
        self.max_priority = max(self.max_priority, float(priorities.max()))
        scaled = priorities**self.alpha
        self.sum_tree.update(idx, scaled)
        self.min_tree.update(idx, scaled)

    def state_dict(self) -> dict[str, Any]:
        """Everything needed to rebuild this replay exactly (arrays + counters + RNG state)."""
        filled = slice(0, self.size)
        return {
            **{key: arr[filled] for key, arr in self.storage.items()},
            "priorities": self.sum_tree.leaves(np.arange(self.size)),
            "counters": np.array([self.cursor, self.size, self.total_added], np.int64),
            "max_priority": np.array(self.max_priority),
            "rng_state": self.rng.bit_generator.state,  # a dict: checkpoint.py stores it as JSON
        }

    def load_state_dict(self, state: dict[str, Any]) -> None:
        size = int(state["counters"][1])
        for key in FIELDS:
            self.storage[key][:size] = state[key]
        idx = np.arange(size)
        # Priorities were saved already raised to alpha; write the leaves directly.
        self.sum_tree.update(idx, state["priorities"])
        self.min_tree.update(idx, state["priorities"])
        self.cursor, self.size, self.total_added = (int(v) for v in state["counters"])
        self.max_priority = float(state["max_priority"])
        self.rng.bit_generator.state = state["rng_state"]
