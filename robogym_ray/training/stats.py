"""A training run's statistics: the counters the loop keeps and the pure functions that turn
them into TensorBoard scalars, evaluation history and the summary (no Ray: unit-tested alone)."""

from __future__ import annotations

from collections import Counter, deque
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from robogym_ray.envs.outcomes import WINDOW_KEYS, rates
from robogym_ray.supervision.restart_policy import FaultCause

if TYPE_CHECKING:  # the rollout worker imports torch; these counters need none of it
    from robogym_ray.experience.rollout import Episode, RolloutResult


@dataclass
class WorkerSlot:
    """Driver-side bookkeeping of one rollout worker."""

    index: int
    handle: Any
    kind: str = "sim"
    steps_since_sync: int = 0
    weights_version: int = -1
    alive: bool = True
    generation: int = 0
    """How many times the worker was replaced."""
    call_started: float = 0.0
    """``time.perf_counter()`` when its running ``collect`` call was sent."""


def no_restarts() -> Counter[str]:
    """A zero count for every ``FaultCause`` (so scalars and summaries list every cause)."""
    return Counter({cause.value: 0 for cause in FaultCause})


@dataclass
class KindStats:
    """One kind of worker's share of the run."""

    env_steps: int = 0
    episodes: int = 0
    statuses: deque[str] = field(default_factory=lambda: deque(maxlen=100))


@dataclass
class RunStats:
    """Counters of one run; ``statuses`` and ``returns`` keep the last 100 episodes."""

    env_steps: int = 0
    episodes: int = 0
    dropped_steps: int = 0
    learner_failures: int = 0
    worker_failures: int = 0
    worker_replacements: int = 0
    evaluator_failures: int = 0
    """Evaluator processes lost (replaced as ``EvalSchedule._take`` says); an evaluation lost
    with a dead learner's weights is not one."""
    transitions_sent: int = 0
    """Transitions the workers sent to the learner (its replay should have them all)."""
    relabelled_transitions: int = 0
    """Of those, the ones hindsight relabelling wrote (``TrainConfig.relabel_goals``)."""
    abandoned_real_calls: int = 0
    """Real-robot calls still running when the run ended (a paused robot), not collected."""
    robot_errors: int = 0
    worker_steps: dict[int, int] = field(default_factory=dict)
    by_kind: dict[str, KindStats] = field(default_factory=dict)
    """Env steps, episodes and last statuses of each kind of worker (``sim``, ``real``), kept
    apart only when a run has more than one kind: a real robot's curve beside the simulations'."""
    statuses: deque[str] = field(default_factory=lambda: deque(maxlen=100))
    """Of the last 100 episodes that were not revisits (their rates are the task's)."""
    revisits: int = 0
    revisit_statuses: deque[str] = field(default_factory=lambda: deque(maxlen=100))
    returns: deque[float] = field(default_factory=lambda: deque(maxlen=100))
    restarts: Counter[str] = field(default_factory=no_restarts)
    """Rebuilds of in-process simulations by cause, as the workers reported them, plus workers
    killed past their deadline (``hung``). The gRPC path's server restarts are the supervisor's
    count only (``record(supervised=True)``): ``all_restarts`` adds them."""
    learner: dict[str, float] = field(default_factory=dict)
    eval: dict[str, float] = field(default_factory=dict)
    eval_history: list[dict[str, float]] = field(default_factory=list)
    learner_restarts: list[dict[str, Any]] = field(default_factory=list)
    """Each learner process Ray restarted: when, where, and what it restored (the loop's)."""


def record(
    stats: RunStats, result: RolloutResult, supervised: bool = False, kind: str = "sim"
) -> list[Episode]:
    """Count a worker's result; returns its episodes that count toward the task's rates.

    Revisited starts are harder than the task's own, so they are counted apart (``revisits``,
    ``revisit_statuses``) and kept out of ``statuses`` and ``returns``.

    ``kind``: the worker's (``sim`` or ``real``), whose own counts ``by_kind`` keeps.

    ``supervised``: the worker's servers are the supervisor's (gRPC path). The supervisor
    restarts them and counts each restart once, by the first cause it saw (often its own probe's
    ``hung`` before the client's ``deadline``); the worker's ``faults`` are the same restarts
    seen from the client, so counting them too would count one fault twice.
    """
    stats.env_steps += result.steps
    stats.dropped_steps += result.dropped
    stats.robot_errors += result.robot_errors
    stats.worker_steps[result.worker] = stats.worker_steps.get(result.worker, 0) + result.steps
    share = stats.by_kind.setdefault(kind, KindStats())
    share.env_steps += result.steps
    share.episodes += len(result.episodes)
    for cause, n in ({} if supervised else result.faults).items():
        stats.restarts[FaultCause.parse(cause).value] += n
    counted = []
    for ep in result.episodes:
        stats.episodes += 1
        if ep.revisit:
            stats.revisits += 1
            stats.revisit_statuses.append(ep.final_status)
            continue
        stats.statuses.append(ep.final_status)
        share.statuses.append(ep.final_status)
        stats.returns.append(ep.ret)
        counted.append(ep)
    return counted


def all_restarts(stats: RunStats, supervisor: Mapping[str, int]) -> dict[str, int]:
    """Every restart of the run by cause: the supervisor's robot servers (gRPC path), the
    in-process simulations and the workers killed as hung (``stats.restarts``)."""
    total = no_restarts()
    total.update(supervisor)
    total.update(stats.restarts)
    return dict(total)


def eval_entry(stats: RunStats, wall_s: float) -> dict[str, float]:
    """One line of ``eval_history`` for the evaluation now in ``stats.eval``."""
    return {
        "wall_s": round(wall_s, 2),
        "env_steps": stats.env_steps,
        "learner_steps": int(stats.learner.get("learner_steps", 0)),
        "return": round(stats.eval["eval_return"], 2),
        "success_rate": stats.eval["eval_success_rate"],
        "snapshot_success_rate": stats.eval["eval_snapshot_success_rate"],
        # A task with command windows: its own measure (the evaluator's medians), m and rad.
        **{key: round(stats.eval[f"eval_{key}"], 5) for key in WINDOW_KEYS
           if f"eval_{key}" in stats.eval},
    }  # fmt: skip


def scalars(
    stats: RunStats,
    *,
    wall_s: float,
    first_learner_step: int,
    noise_scale: float,
    weights_versions: Sequence[int],
    restarts: Mapping[str, int],
    best_snapshot_rate: float | None = None,
) -> dict[str, float]:
    """Everything the run writes to TensorBoard, from its counters."""
    s, wall = stats, max(1e-9, wall_s)
    learner_steps = s.learner.get("learner_steps", 0.0)
    # No rate before the first finished episode: a 0 there would read as "never succeeds".
    out = {f"train/{k}": v for k, v in rates(s.statuses).items()} if s.statuses else {}
    out.update({f"eval/{k.removeprefix('eval_')}": v for k, v in s.eval.items()})
    if s.revisit_statuses:
        out["explore/revisit_success_rate"] = rates(s.revisit_statuses)["success_rate"]
    if best_snapshot_rate is not None:
        out["eval/best_snapshot_success_rate"] = best_snapshot_rate
    out.update({
        "train/return_last100": float(np.mean(s.returns)) if s.returns else 0.0,
        "throughput/env_steps_per_s": s.env_steps / wall,
        "throughput/learner_steps_per_s": max(0.0, learner_steps - first_learner_step) / wall,
        "replay/size": s.learner.get("replay_size", 0.0),
        "replay/mean_priority": s.learner.get("mean_priority", 0.0),
        "loss/critic": s.learner.get("critic_loss", 0.0),
        "loss/policy": s.learner.get("policy_loss", 0.0),
        "learner/mean_q": s.learner.get("mean_q", 0.0),
        "learner/policy_change": s.learner.get("policy_change", 0.0),
        "learner/lr_scale": s.learner.get("lr_scale", 1.0),
        "explore/noise_scale": noise_scale,
        "explore/revisit_fraction": s.revisits / max(1, s.episodes),
        "learner/steps": learner_steps,
        "weights/lag": learner_steps - min(weights_versions, default=learner_steps),
        "faults/dropped_steps": float(s.dropped_steps),
        "faults/learner_failures": float(s.learner_failures),
        "faults/worker_failures": float(s.worker_failures),
        "faults/worker_replacements": float(s.worker_replacements),
        "faults/evaluator_failures": float(s.evaluator_failures),
        "faults/robot_errors": float(s.robot_errors),
    })  # fmt: skip
    out.update({f"restarts/{cause}": float(n) for cause, n in restarts.items()})
    if len(s.by_kind) > 1:  # a real robot beside simulations: each kind's own curve
        for kind, share in s.by_kind.items():
            out[f"{kind}/env_steps"] = float(share.env_steps)
            out[f"{kind}/episodes"] = float(share.episodes)
            if share.statuses:
                out[f"{kind}/success_rate"] = rates(share.statuses)["success_rate"]
    return out


def summary(stats: RunStats, final: Mapping[str, float], **facts: Any) -> dict[str, Any]:
    """``summary.json``: ``facts`` about the run (task, wall_s, checkpoint, ...), the counters,
    and the final ``scalars`` rounded."""
    return {
        **facts,
        "env_steps": stats.env_steps,
        "episodes": stats.episodes,
        "learner_steps": int(final["learner/steps"]),
        "dropped_steps": stats.dropped_steps,
        "worker_steps": {str(k): v for k, v in sorted(stats.worker_steps.items())},
        "by_kind": {
            kind: {
                "env_steps": share.env_steps,
                "episodes": share.episodes,
                "statuses_last100": dict(Counter(share.statuses)),
            }
            for kind, share in stats.by_kind.items()
        },  # fmt: skip
        "robot_errors": stats.robot_errors,
        "abandoned_real_calls": stats.abandoned_real_calls,
        "eval_history": stats.eval_history,
        "learner_restarts": stats.learner_restarts,
        "final_status_counts": dict(Counter(stats.statuses)),
        "revisited_episodes": stats.revisits,
        "relabelled_transitions": stats.relabelled_transitions,
        **{k: round(v, 4) for k, v in final.items()},
    }


def run_root(summary: Mapping[str, Any]) -> str:
    """The run's folder (a path or an object store's URI) that a ``summary.json`` names.

    ``logdir`` names it; summaries written before it was the one field also had it as
    ``storage.root``, which this still reads when ``logdir`` is missing.

    Raises:
        KeyError: the summary names neither.
    """
    if "logdir" in summary:
        return str(summary["logdir"])
    storage = summary.get("storage")
    if isinstance(storage, Mapping) and "root" in storage:
        return str(storage["root"])
    raise KeyError("summary.json names no run folder (neither 'logdir' nor 'storage.root')")
