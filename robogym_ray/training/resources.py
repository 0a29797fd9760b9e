"""What each actor of a run reserves from Ray, in one table: the builder (``program.py``) starts
every actor with its row's options, ``check_resources`` sums the rows against the cluster, and a
sweep turns the rows into a trial's placement-group bundles (one bundle per actor), so the three
cannot disagree.

A custom resource (``--learner-resource`` ...) marks the nodes an actor may run on: the actor
asks for a token 0.01 of it, which says where, not how many.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from robogym_ray.training.config import TrainConfig

MARK = 0.01
"""The amount of a custom resource an actor asks for: it marks nodes, it does not count actors."""


@dataclass(frozen=True)
class ActorNeed:
    """One kind of actor of a run and what each of them reserves."""

    role: str
    count: int
    cpus: float
    gpus: float = 0.0
    marks: tuple[str, ...] = ()
    """Custom resources the actor requires (a token ``MARK`` of each)."""

    def options(self) -> dict[str, Any]:
        """The Ray options that reserve this (``num_cpus``, ``num_gpus``, ``resources``)."""
        out: dict[str, Any] = {"num_cpus": self.cpus}
        if self.gpus:
            out["num_gpus"] = self.gpus
        if self.marks:
            out["resources"] = {name: MARK for name in self.marks}
        return out

    def bundle(self) -> dict[str, float]:
        """One actor's placement-group bundle."""
        out = {"CPU": self.cpus, **{name: MARK for name in self.marks}}
        if self.gpus:
            out["GPU"] = self.gpus
        return out


def actor_needs(cfg: TrainConfig, learner_gpus: float = 0.0) -> tuple[ActorNeed, ...]:
    """Every actor ``cfg`` starts (``learner_gpus``: the learner's, ``-1`` resolved)."""
    return tuple(n for n in _table(cfg, learner_gpus) if n.count > 0)


def actor_need(cfg: TrainConfig, role: str, learner_gpus: float = 0.0) -> ActorNeed:
    """The row of ``role`` ("learner", "robot server", ...): what each such actor reserves,
    also while ``cfg`` starts none (a supervisor's robot servers start on demand)."""
    table = _table(cfg, learner_gpus)
    for need in table:
        if need.role == role:
            return need
    raise ValueError(f"no actor {role!r} in a run; roles: {', '.join(n.role for n in table)}")


def _table(cfg: TrainConfig, learner_gpus: float) -> list[ActorNeed]:
    """Every kind of actor, counted or not.

    With in-process robots ``--server-resource`` places the simulating actors themselves (their
    robots run in them); real-robot workers go anywhere (they reach their robot through its
    real-robot actor, which Ray places with its own 0.05 CPU).
    """
    sims = (cfg.server_resource,) if cfg.sim_path == "inprocess" and cfg.server_resource else ()
    servers = cfg.workers * cfg.envs_per_worker + int(cfg.evaluator)
    return [
        ActorNeed("learner", 1, cfg.learner_cpus, learner_gpus,
                  (cfg.learner_resource,) if cfg.learner_resource else ()),
        ActorNeed("rollout worker", cfg.workers, cfg.worker_cpus,
                  marks=tuple(m for m in (cfg.worker_resource, *sims) if m)),
        ActorNeed("real-robot worker", len(cfg.real_robot), cfg.worker_cpus),
        ActorNeed("real robot", len(cfg.real_robot), 0.05),
        ActorNeed("evaluator", int(cfg.evaluator), cfg.evaluator_cpus,
                  marks=tuple(m for m in (cfg.evaluator_resource, *sims) if m)),
        # Counted on every path (as the CPU check always did): 0.05 of slack in-process.
        ActorNeed("supervisor", 1, 0.05),
        # One robot-server actor per env on the gRPC path (started by the supervisor).
        ActorNeed("robot server", servers if cfg.sim_path == "grpc" else 0, cfg.server_cpus,
                  marks=(cfg.server_resource,) if cfg.server_resource else ()),
    ]  # fmt: skip


def total_cpus(needs: Sequence[ActorNeed]) -> float:
    return sum(n.count * n.cpus for n in needs)


def describe(needs: Sequence[ActorNeed]) -> str:
    """``learner 0.5 CPU + 2 rollout worker x 0.25 CPU + ...``."""
    parts = []
    for n in needs:
        gpu = f" + {n.gpus:g} GPU" if n.gpus else ""
        parts.append(f"{n.count} {n.role} x {n.cpus:g} CPU{gpu}" if n.count > 1
                     else f"{n.role} {n.cpus:g} CPU{gpu}")  # fmt: skip
    return " + ".join(parts)
