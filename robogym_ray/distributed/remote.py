"""The Ray edge, learning side: the rollout workers, the evaluator and the learner as actors
(``robot_actors.py`` is the robot side: the supervisor, robot-server and real-robot actors).
These two modules are the only ones that wrap this package's plain classes with ``ray.remote``.

Ray mechanisms used, and why:

* Fractional ``num_cpus`` everywhere.
* **The learner actor has ``max_restarts``**: Ray re-runs its constructor after a crash, which
  restores the latest checkpoint (``LearnerService``), so training resumes where it was.
* Weights travel through the object store: the driver passes the ObjectRef of the learner's
  ``get_weights()`` result to the workers; Ray resolves it once per node.
* Transitions go from each rollout worker to the learner directly (``learner.add.remote`` in
  the worker); the driver receives the reference of the learner's answer, for its counters.
"""

from __future__ import annotations

import dataclasses
import math
import os
import socket
from typing import Any

import ray

from robogym_ray.experience.evaluator import Evaluator
from robogym_ray.experience.rollout import RolloutResult, RolloutWorker
from robogym_ray.learner.config import D4PGConfig
from robogym_ray.learner.service import LearnerService


class _Rollout(RolloutWorker):
    """A rollout worker that sends its batches to the learner itself: the driver gets counters
    and the reference of the learner's answer, never the transitions."""

    def __init__(self, *args: Any, learner: Any = None, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.learner = learner

    def collect(self, num_steps: int, noise_scale: float = 1.0) -> RolloutResult:
        result = super().collect(num_steps, noise_scale)
        if self.learner is not None and result.batch is not None:
            result.learner_call = self.learner.add.remote(result.batch)
            result.batch = None
        return result

    def set_weights(self, weights_and_version: tuple[dict, int]) -> None:  # type: ignore[override]
        weights, version = weights_and_version
        super().set_weights(weights, version)

    def pid(self) -> int:
        return os.getpid()


class _Evaluator(Evaluator):
    def evaluate(  # type: ignore[override]
        self, weights_and_version: tuple[dict, int], episodes: int = 1, seed_base: int | None = None
    ) -> dict:
        weights, version = weights_and_version
        return super().evaluate(weights, version, episodes, seed_base)

    def ping(self) -> int:
        return os.getpid()

    def status(self) -> dict[str, int]:
        """Its process and the episodes it has played (a replacement's count goes on)."""
        return {"pid": os.getpid(), "episodes": self.episodes}


class _Learner(LearnerService):
    def __init__(self, d4pg: D4PGConfig, *args: Any, **kwargs: Any) -> None:
        if d4pg.num_threads == 0:
            # The CPUs Ray reserved for this actor are its threads: a learner given 8 cores
            # uses 8 without a second setting. Ray's own OMP_NUM_THREADS comes too late for a
            # torch imported before the actor starts, and a user's shell may have set it.
            d4pg = dataclasses.replace(d4pg, num_threads=assigned_threads())
        super().__init__(d4pg, *args, **kwargs)

    def status(self) -> dict[str, Any]:
        """``LearnerService.status``, the node it runs on (it moves with a lost node), its torch
        threads and device."""
        import torch

        return {
            **super().status(),
            "node": node_label(),
            "threads": torch.get_num_threads(),
            "device": str(self.learner.device),
        }


def assigned_threads() -> int:
    """Ray's CPUs for this actor as a thread count: rounded down, at least 1 (Ray's rule for
    OMP_NUM_THREADS)."""
    cpus = ray.get_runtime_context().get_assigned_resources().get("CPU", 1.0)
    return max(1, math.floor(cpus + 1e-9))


def node_label() -> str:
    """This process's machine as a user finds it in a cluster: host name and address."""
    return f"{socket.gethostname()} ({ray.util.get_node_ip_address()})"


RolloutActor = ray.remote(_Rollout)
LearnerActor = ray.remote(_Learner)
EvaluatorActor = ray.remote(_Evaluator)
