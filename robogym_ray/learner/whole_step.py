"""The whole learner step as one device program: one CUDA graph per block on a GPU, eager on a CPU.

Why: on an H100 the learner's step with compiled losses left the GPU idle 78-88 % of the time
(docs/benchmarks.md 15e): the host's kernel launches and its small reads of device values (the
replay's total, the schedules, the priorities' maximum) set the pace, not the arithmetic. Here
the draws, the prioritized sampling, both gradient updates, the priority write-back, the target
and Polyak updates and the metrics of a block of ``sgd_steps_per_sample`` steps are captured once
in a CUDA graph and replayed: one launch per block, no host value read.

What makes a step capturable, and what it changes:

- the uniform draws come from torch's default generator on the learner's device (graph-safe on
  every torch this runs on; the learner seeds it, its process draws nothing else from it, and a
  checkpoint keeps its state), not from the replay's NumPy generator: for one seed the sampled
  indices differ from the host-stepped path's; given the same draws the steps are the same, bit
  for bit on a CPU (tests/learner/test_whole_step.py);
- the step counter lives on the device, and the importance exponent, the learning rates (Adam
  with tensor rates, capturable on CUDA) and the hard target copies (a ``where`` on the counter)
  are computed from it there;
- the replay's fill level and running maximum are device values, changed in place;
- the metrics are summed on the device and read once per ``run`` call.

The first ``WARMUP`` blocks run eagerly on a side stream (real learner steps: cuBLAS and Adam's
state are set up before the capture); a restore drops the graph (Adam's state is new memory) and
the next block captures it again. A block shorter than ``sgd_steps_per_sample`` (the end of a
``run`` call) runs eagerly, the same code.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, ClassVar, Protocol

import torch

from robogym_ray.learner.schedules import importance_beta, lr_scale

if TYPE_CHECKING:
    from robogym_ray.learner.config import D4PGConfig
    from robogym_ray.learner.replay import PrioritizedReplay

WARMUP = 3
"""Eager blocks before a capture (PyTorch's CUDA-graph notes ask for a few on a side stream)."""


class SteppedLearner(Protocol):
    """What the whole step needs of a learner (``D4PGLearner`` is one): its settings, device,
    replay and counter, and the three updates it runs inside a block."""

    STATS: ClassVar[tuple[str, ...]]
    """The names of the statistics ``gradient_step`` returns, in their order."""
    config: D4PGConfig
    device: torch.device
    replay: PrioritizedReplay
    num_steps: int

    def set_lr(self, step: Any) -> Any: ...

    def gradient_step(
        self, b: dict[str, torch.Tensor], w: torch.Tensor
    ) -> tuple[torch.Tensor, torch.Tensor]: ...

    def update_targets(self, due: torch.Tensor | None = None) -> None: ...


class WholeStep:
    """Blocks of learner steps that read no host value; a full block captured once on CUDA."""

    def __init__(self, learner: SteppedLearner) -> None:
        self.learner = learner
        device = learner.device
        self.captures_graph = device.type == "cuda"
        """Whether a full block is captured in a CUDA graph and replayed (else run eagerly)."""
        self.step = torch.zeros((), dtype=torch.float64, device=device)
        """The learner's step count as the device sees it (``learner.num_steps``)."""
        self.sums = torch.zeros(len(learner.STATS), dtype=torch.float32, device=device)
        self.graph: torch.cuda.CUDAGraph | None = None
        """The captured full block (``sgd_steps_per_sample`` steps): the only one replayed."""
        self.eager_blocks = 0
        self.draw = self._uniform
        """Where a block's uniform draws come from (a test aligns them with the host path's)."""

    def _uniform(self, n: int) -> torch.Tensor:
        return torch.rand(n, dtype=torch.float64, device=self.learner.device)

    def forget(self) -> None:
        """After a restore: new optimizer state and counters, so capture again."""
        self.graph = None
        self.eager_blocks = 0
        self.step.fill_(self.learner.num_steps)

    def run(self, steps: int) -> tuple[Any, float, float]:
        """``steps`` learner steps in blocks of ``sgd_steps_per_sample``: (the metrics' means,
        the summed importance exponent and learning-rate scale). The schedules' values are the
        host's copies of what the device computed from the same counter."""
        learner, done, beta_sum, lr_sum = self.learner, 0, 0.0, 0.0
        c = learner.config
        while done < steps:
            k = min(c.sgd_steps_per_sample, steps - done)
            beta_sum += k * importance_beta(c, learner.num_steps)
            lr_sum += sum(lr_scale(c, learner.num_steps + j) for j in range(k))
            self.run_block(k)
            learner.num_steps += k
            done += k
        return (self.take_sums() / steps).numpy(), beta_sum, lr_sum

    def run_block(self, k: int) -> None:
        """``k`` learner steps from one sampled block (``learner.num_steps`` is the caller's)."""
        full = k == self.learner.config.sgd_steps_per_sample
        if not (self.captures_graph and full):
            self._block(k)
            return
        if self.graph is not None:
            self.graph.replay()
            return
        side = torch.cuda.Stream()
        side.wait_stream(torch.cuda.current_stream())
        with torch.cuda.stream(side):
            if self.eager_blocks < WARMUP:
                self._block(k)
                self.eager_blocks += 1
            else:
                graph = torch.cuda.CUDAGraph()
                # thread_local: the actor's own thread may copy an insert meanwhile.
                with torch.cuda.graph(graph, capture_error_mode="thread_local"):
                    self._block(k)
                self.graph = graph
        torch.cuda.current_stream().wait_stream(side)
        if self.graph is not None:
            self.graph.replay()  # a capture records the block without running it

    def take_sums(self) -> torch.Tensor:
        """The summed statistics since the last call, on the host; the device's are zeroed."""
        out = self.sums.to("cpu", copy=True)  # on a CPU, .cpu() would be the same memory
        self.sums.zero_()
        return out

    def _block(self, k: int) -> None:
        learner, c = self.learner, self.learner.config
        beta = importance_beta(c, self.step)  # the block's first step's, as the host path's
        draws = self.draw(k * c.batch_size)
        batch, idx, weights = learner.replay.sample_drawn(draws, beta)
        for j in range(k):
            part = slice(j, None, k)
            learner.set_lr(self.step)
            b = {key: v[part] for key, v in batch.items()}
            stats, per_sample = learner.gradient_step(b, weights[part])
            if c.prioritized:
                learner.replay.update_priorities(idx[part], per_sample)
            self.step += 1
            learner.update_targets(due=self._copy_due())
            self.sums += stats

    def _copy_due(self) -> Any:
        """Whether this step's hard target copy is due: a device bool (None with Polyak)."""
        c = self.learner.config
        return None if c.target_tau > 0 else torch.remainder(self.step, c.target_update_period) == 0
