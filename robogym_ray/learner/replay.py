"""Proportional prioritized replay (Schaul et al. 2016; Ape-X): segment trees on the host, flat
leaves on a torch device.

All priority operations work on whole batches. In host memory, updates propagate level by level
through a sum and a min tree with NumPy fancy indexing, and sampling descends the tree for every
sample at once (``log2(capacity)`` vector steps per batch, no Python loop per sample).

One implementation for two homes: NumPy arrays in host memory (the CPU learner's, as always), or
torch tensors on the learner's device (``Backend.torch_on``), so a GPU learner samples, gathers and
writes priorities back without a host round trip. There the priorities are flat leaves
(:class:`FlatTree`: fewer, larger operations, as a GPU wants). The uniform draws come from the same
host NumPy generator on both, so for one seed and insert order both sample the same indices with
the same weights, up to float64 round-off: the totals and prefix sums add in another order than
the trees', which can move a draw within round-off of a boundary to the neighbouring slot and
change a weight's last bits.

The whole-step learner (``learner/whole_step.py``) samples with draws it makes on its device
(:meth:`PrioritizedReplay.sample_drawn`): no host value enters, so a CUDA graph can hold it. For
that the fill level and the running maximum priority are arrays of the backend, changed in place.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from robogym_ray.errors import ConfigError

FIELDS = ("obs", "action", "reward", "discount", "next_obs")


class Backend:
    """Where the replay's arrays live: host NumPy (``Backend()``) or a torch device."""

    def __init__(self, device: Any = None) -> None:
        self.device = device
        """``None``: NumPy in host memory; else the ``torch.device`` holding every array."""
        if device is not None:
            import torch  # only the learner's process pays for torch here

            self.torch = torch

    @classmethod
    def torch_on(cls, device: Any) -> Backend:
        import torch

        return cls(torch.device(device))

    @property
    def on_host(self) -> bool:
        return self.device is None

    def full(self, n: int, value: Any, dtype: str = "float64") -> Any:
        if self.on_host:
            return np.full(n, value, dtype=dtype)
        out = self.torch.empty(n, dtype=getattr(self.torch, dtype), device=self.device)
        return out.copy_(self.asarray(value).expand(n)) if n else out

    def zeros(self, shape: tuple[int, ...], dtype: str) -> Any:
        if self.on_host:
            return np.zeros(shape, dtype)
        return self.torch.zeros(shape, dtype=getattr(self.torch, dtype), device=self.device)

    def asarray(self, value: Any, dtype: str | None = None) -> Any:
        """``value`` (array, tensor or number) here, in ``dtype`` when given."""
        if self.on_host:
            return np.asarray(value, dtype=dtype)
        t = self.torch
        # The dtype goes in with the value: a Python float made a tensor first is float32, and
        # a restored max priority lost its last digits that way.
        return t.as_tensor(value, dtype=getattr(t, dtype) if dtype else None, device=self.device)

    def upload(self, array: np.ndarray) -> Any:
        """A host array here. To a GPU through pinned memory without waiting: a plain copy from
        pageable memory would first wait for every kernel queued before it."""
        if self.on_host or self.device.type != "cuda":
            return self.asarray(array)
        host = self.torch.from_numpy(np.ascontiguousarray(array)).pin_memory()
        return host.to(self.device, non_blocking=True)

    def arange(self, n: int) -> Any:
        """0, 1, ..., n - 1 as float64 here (made on a device: no host copy)."""
        if self.on_host:
            return np.arange(n, dtype=np.float64)
        return self.torch.arange(n, dtype=self.torch.float64, device=self.device)

    def set_(self, dst: Any, value: Any) -> None:
        """Write ``value`` into the 0-d array ``dst`` in place (a captured graph keeps reading
        ``dst``'s memory, so it is never replaced)."""
        if self.on_host:
            dst[...] = value
        else:
            dst.copy_(self.asarray(value, str(dst.dtype).removeprefix("torch.")))

    def to_numpy(self, value: Any) -> np.ndarray:
        return value if self.on_host else value.detach().cpu().numpy()

    def op(self, name: str) -> Any:
        """An elementwise function of this backend by its name (``add``, ``minimum``, ...)."""
        return getattr(np if self.on_host else self.torch, name)


class SegmentTree:
    """Complete binary tree over ``capacity`` leaves (rounded up to a power of two).

    Node ``i`` has children ``2i`` and ``2i+1``; leaves live at ``[size, 2 * size)``; node 1 is
    the root. ``op`` is ``np.add`` (sum tree) or ``np.minimum`` (min tree).
    """

    def __init__(
        self, capacity: int, op: str, neutral: float, backend: Backend | None = None
    ) -> None:
        self.size = 1 << max(0, int(capacity - 1).bit_length())
        self.depth = self.size.bit_length() - 1
        self.backend = backend or Backend()
        self.op = self.backend.op(op)
        self.neutral = neutral
        self.nodes = self.backend.full(2 * self.size, neutral)

    def update(self, indices: Any, values: Any) -> None:
        """Set leaves ``indices`` to ``values`` (last write wins on duplicates) and re-reduce."""
        idx = self.backend.asarray(indices, "int64") + self.size
        self.nodes[idx] = values
        for _ in range(self.depth):
            # Children are final before their parents are written, so duplicate parents all get
            # the same value: no np.unique (a sort per level) needed.
            idx = idx >> 1
            self.nodes[idx] = self.op(self.nodes[2 * idx], self.nodes[2 * idx + 1])

    def leaves(self, indices: Any) -> Any:
        return self.nodes[self.backend.asarray(indices, "int64") + self.size]

    @property
    def root(self) -> float:
        return float(self.nodes[1])

    @property
    def root_value(self) -> Any:
        """The root where it lives (a device tensor: reading it as a float would wait on it)."""
        return self.nodes[1]


class SumTree(SegmentTree):
    def __init__(self, capacity: int, backend: Backend | None = None) -> None:
        super().__init__(capacity, "add", 0.0, backend)

    def find_prefix(self, mass: Any) -> Any:
        """Leaf index ``i`` per query with ``sum(p[:i]) <= mass < sum(p[:i+1])``, vectorized."""
        mass = self.backend.asarray(mass, "float64")
        idx = self.backend.full(len(mass), 1, "int64")
        for _ in range(self.depth):
            left = self.nodes[2 * idx]
            go_right = mass >= left
            mass = mass - left * go_right  # exact: left or 0 subtracted, as np.where did
            idx = 2 * idx + go_right
        return idx - self.size


class MinTree(SegmentTree):
    def __init__(self, capacity: int, backend: Backend | None = None) -> None:
        super().__init__(capacity, "minimum", np.inf, backend)


class FlatTree:
    """A tree's interface over its leaves alone: the layout of a replay on a torch device.

    A tree update costs about eight small operations per level (17 levels at 100,000 slots) and
    a descent seven, each a kernel launch on a GPU; there the launches, not the arithmetic, set
    the step's time (an H100 made ~80 learner steps/s at every batch from 256 to 16,384, with
    the losses compiled too: docs/benchmarks.md). Here an update is one scatter, the root one
    reduction and the prefix search a cumulative sum and a binary search: O(capacity) work in
    one or two launches, which a GPU does in microseconds and a CPU in about 0.1 ms per
    100,000 slots. The prefix sums add in another order than the tree's, so a draw within
    float64 round-off of a boundary may pick the neighbouring slot.
    """

    def __init__(self, capacity: int, reduce: str, neutral: float, backend: Backend) -> None:
        self.backend = backend
        self.reduce = backend.op(reduce)
        self.nodes = backend.full(capacity, neutral)
        """The leaves (named as the tree's array, which holds them among its nodes)."""

    def update(self, indices: Any, values: Any) -> None:
        self.nodes[self.backend.asarray(indices, "int64")] = values

    def leaves(self, indices: Any) -> Any:
        return self.nodes[self.backend.asarray(indices, "int64")]

    @property
    def root(self) -> float:
        return float(self.root_value)

    @property
    def root_value(self) -> Any:
        return self.reduce(self.nodes)

    def find_prefix(self, mass: Any) -> Any:
        """:meth:`SumTree.find_prefix`'s answer: the slot whose prefix-sum interval holds it."""
        b = self.backend
        cumulative = b.op("cumsum")(self.nodes, 0)
        return b.op("searchsorted")(cumulative, b.asarray(mass, "float64"), side="right")


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
        backend: Backend | None = None,
    ) -> None:
        if capacity < 1:
            raise ConfigError(f"replay capacity={capacity}; expected >= 1")
        self.capacity, self.alpha, self.eps = capacity, alpha, eps
        self.backend = b = backend or Backend()
        self.storage: dict[str, Any] = {
            "obs": b.zeros((capacity, obs_dim), "float32"),
            "action": b.zeros((capacity, act_dim), "float32"),
            "reward": b.zeros((capacity,), "float32"),
            "discount": b.zeros((capacity,), "float32"),
            "next_obs": b.zeros((capacity, obs_dim), "float32"),
        }
        if b.on_host:
            self.sum_tree, self.min_tree = SumTree(capacity, b), MinTree(capacity, b)
        else:  # a device's kernel launches cost more than its O(capacity) work: FlatTree
            self.sum_tree = FlatTree(capacity, "sum", 0.0, b)
            self.min_tree = FlatTree(capacity, "amin", np.inf, b)
        self._max_priority = b.asarray(1.0, "float64")
        """Where the priorities live: on a device, reading it would wait for the device."""
        self._fill = b.asarray(0, "int64")
        """``size`` where the priorities live, for a sampler that reads no host value."""
        self._zero = b.asarray(0.0, "float64")
        self.cursor = 0  # next slot to write; the oldest transition once full
        self.size = 0
        self.total_added = 0
        self.rng = np.random.default_rng(seed)

    def __len__(self) -> int:
        return self.size

    @property
    def max_priority(self) -> float:
        return float(self._max_priority)

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
        b = self.backend
        idx = b.upload((self.cursor + np.arange(count)) % self.capacity)
        for key in FIELDS:
            self.storage[key][idx] = b.upload(np.asarray(batch[key], np.float32))
        if priorities is None:
            priorities = b.full(count, self._max_priority)
        self._set_priorities(idx, b.asarray(priorities, "float64"))
        self.cursor = int((self.cursor + count) % self.capacity)
        self.size = min(self.size + count, self.capacity)
        b.set_(self._fill, self.size)
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
        # One uniform draw per equal-mass stratum lowers variance versus i.i.d. draws. The
        # draws are the host generator's on every backend (the same samples for one seed).
        return self.sample_drawn(self.backend.upload(self.rng.random(batch_size)), beta)

    def sample_drawn(self, draws: Any, beta: Any) -> tuple[dict[str, Any], Any, Any]:
        """:meth:`sample` with its uniform draws in [0, 1) given, one per sample, as an array of
        this backend; ``beta`` a number or a 0-d array. Reads no host value: on a device, a CUDA
        graph can capture it. The replay must not be empty."""
        b, n = self.backend, len(draws)
        total = self.sum_tree.root_value
        mass = (b.arange(n) + draws) * (total / n)  # draw j lands in stratum j of n
        below_total = b.op("nextafter")(total, self._zero)
        idx = self.sum_tree.find_prefix(b.op("minimum")(mass, below_total))
        # Float round-off can walk into an empty leaf past the filled region; clamp back.
        idx = b.op("minimum")(idx, self._fill - 1)
        probs = self.sum_tree.leaves(idx) / total
        min_prob = self.min_tree.root_value / total
        weights = (probs / min_prob) ** (-beta)  # == (N P)^-b / (N P_min)^-b
        batch = {key: self.storage[key][idx] for key in FIELDS}
        return batch, idx, b.asarray(weights, "float32")

    def update_priorities(self, indices: Any, priorities: Any) -> None:
        """Write back learner-computed priorities (e.g. per-sample loss) for sampled slots."""
        b = self.backend
        self._set_priorities(b.asarray(indices, "int64"), b.asarray(priorities, "float64"))

    def _set_priorities(self, idx: Any, priorities: Any) -> None:
        priorities = abs(priorities) + self.eps
        b = self.backend
        b.set_(self._max_priority, b.op("maximum")(self._max_priority, priorities.max()))
        scaled = priorities**self.alpha
        self.sum_tree.update(idx, scaled)
        self.min_tree.update(idx, scaled)

    def state_dict(self) -> dict[str, Any]:
        """Everything needed to rebuild this replay exactly (arrays + counters + RNG state)."""
        filled, host = slice(0, self.size), self.backend.to_numpy
        return {
            **{key: host(arr[filled]) for key, arr in self.storage.items()},
            "priorities": host(self.sum_tree.leaves(np.arange(self.size))),
            "counters": np.array([self.cursor, self.size, self.total_added], np.int64),
            "max_priority": np.array(self.max_priority),
            "rng_state": self.rng.bit_generator.state,  # a dict: checkpoint.py stores it as JSON
        }

    def load_state_dict(self, state: dict[str, Any]) -> None:
        size, b = int(state["counters"][1]), self.backend
        for key in FIELDS:
            self.storage[key][:size] = b.asarray(state[key], "float32")
        idx = np.arange(size)
        # Priorities were saved already raised to alpha; write the leaves directly.
        self.sum_tree.update(idx, b.asarray(state["priorities"], "float64"))
        self.min_tree.update(idx, b.asarray(state["priorities"], "float64"))
        self.cursor, self.size, self.total_added = (int(v) for v in state["counters"])
        b.set_(self._fill, self.size)
        b.set_(self._max_priority, float(state["max_priority"]))
        self.rng.bit_generator.state = state["rng_state"]
