"""The training run's statistics as pure functions: no Ray, no actors."""

from __future__ import annotations

import pytest

from robogym_ray.experience.rollout import Episode, RolloutResult
from robogym_ray.training import stats
from robogym_ray.training.stats import RunStats


def result(worker: int, steps: int, *episodes: Episode, dropped: int = 0) -> RolloutResult:
    return RolloutResult(None, list(episodes), steps=steps, dropped=dropped, worker=worker)


def test_record_counts_steps_and_keeps_revisits_out_of_the_task_rates() -> None:
    s = RunStats()
    counted = stats.record(
        s,
        result(
            0, 50,
            Episode(10.0, 20, "success", 0),
            Episode(-5.0, 30, "collision", 0, revisit=True),
            dropped=3,
        ),
    )  # fmt: skip
    stats.record(s, result(1, 40, Episode(1.0, 40, "max_steps_exceeded", 1)))
    assert [e.final_status for e in counted] == ["success"]
    assert (s.env_steps, s.episodes, s.revisits, s.dropped_steps) == (90, 3, 1, 3)
    assert s.worker_steps == {0: 50, 1: 40}
    assert list(s.statuses) == ["success", "max_steps_exceeded"]
    assert list(s.revisit_statuses) == ["collision"] and list(s.returns) == [10.0, 1.0]


def test_all_restarts_adds_the_supervisors_to_the_runs_own() -> None:
    s = RunStats()
    stats.record(s, RolloutResult(None, [], steps=5, worker=0, faults={"invalid_state": 2}))
    s.restarts["hung"] += 1  # a worker the loop killed past its deadline
    total = stats.all_restarts(s, {"connection": 3, "hung": 1})
    assert total["connection"] == 3 and total["invalid_state"] == 2 and total["hung"] == 2
    assert total["manual"] == 0  # every cause is listed, zeros included
    assert s.restarts["hung"] == 1  # the run's own counter is left as it was


def test_a_supervised_servers_faults_are_the_supervisors_count_only() -> None:
    """gRPC path: the supervisor restarted the server and counted it (by its first cause); the
    worker's client saw the same fault, which is no second restart."""
    s = RunStats()
    faults = {"deadline": 1}
    stats.record(s, RolloutResult(None, [], steps=5, worker=0, faults=faults), supervised=True)
    total = stats.all_restarts(s, {"hung": 1})
    assert sum(total.values()) == 1 and total["hung"] == 1
    stats.record(s, RolloutResult(None, [], steps=5, worker=0, faults=faults))  # in-process
    assert stats.all_restarts(s, {})["deadline"] == 1


def scalars(s: RunStats, **kw) -> dict[str, float]:
    args = dict(
        wall_s=10.0, first_learner_step=100, noise_scale=0.5, weights_versions=[150, 90],
        restarts={"crash": 2},
    )  # fmt: skip
    return stats.scalars(s, **{**args, **kw})


def test_scalars_say_no_rate_before_an_episode_and_the_rates_after() -> None:
    s = RunStats(env_steps=500, learner={"learner_steps": 200.0, "replay_size": 480.0})
    out = scalars(s)
    assert "train/success_rate" not in out  # a 0 there would read as "never succeeds"
    assert out["throughput/env_steps_per_s"] == pytest.approx(50.0)
    assert out["throughput/learner_steps_per_s"] == pytest.approx(10.0)  # this run's steps
    assert out["weights/lag"] == 110.0 and out["restarts/crash"] == 2.0
    assert out["explore/noise_scale"] == 0.5 and out["replay/size"] == 480.0
    stats.record(s, result(0, 10, Episode(1.0, 5, "success", 0), Episode(0.0, 5, "collision", 0)))
    out = scalars(s, best_snapshot_rate=0.9)
    assert out["train/success_rate"] == 0.5 and out["train/collision_rate"] == 0.5
    assert out["train/return_last100"] == 0.5 and out["eval/best_snapshot_success_rate"] == 0.9


def test_a_real_robot_beside_simulations_gets_its_own_counts_and_curve() -> None:
    s = RunStats(env_steps=0)
    stats.record(s, result(0, 30, Episode(1.0, 30, "success", 0)))
    assert not any(k.startswith(("sim/", "real/")) for k in scalars(s))  # one kind: no split
    stats.record(s, result(2, 12, Episode(0.0, 12, "max_steps_exceeded", 2)), kind="real")
    stats.record(s, result(2, 8, Episode(1.0, 8, "success", 2)), kind="real")
    out = scalars(s)
    assert (out["real/env_steps"], out["real/episodes"], out["real/success_rate"]) == (20, 2, 0.5)
    assert (out["sim/env_steps"], out["sim/episodes"], out["sim/success_rate"]) == (30, 1, 1.0)
    summary = stats.summary(s, {"learner/steps": 0.0})
    assert summary["by_kind"]["real"] == {
        "env_steps": 20, "episodes": 2,
        "statuses_last100": {"max_steps_exceeded": 1, "success": 1},
    }  # fmt: skip


def test_run_root_is_logdir_or_an_older_summarys_storage_root() -> None:
    assert stats.run_root({"logdir": "/r/a", "storage": {"node": "vm"}}) == "/r/a"
    older = {"storage": {"root": "s3://b/r/a", "node": "(object store)"}}
    assert stats.run_root(older) == "s3://b/r/a"
    with pytest.raises(KeyError, match="neither 'logdir' nor 'storage.root'"):
        stats.run_root({"storage": {"node": "vm"}})


def test_eval_entry_and_summary() -> None:
    s = RunStats(env_steps=1000, learner={"learner_steps": 120.0})
    s.eval = {"eval_return": 12.345, "eval_success_rate": 0.5, "eval_snapshot_success_rate": 1.0}
    entry = stats.eval_entry(s, wall_s=3.14159)
    assert entry == {
        "wall_s": 3.14, "env_steps": 1000, "learner_steps": 120, "return": 12.35,
        "success_rate": 0.5, "snapshot_success_rate": 1.0,
    }  # fmt: skip
    final = scalars(s)
    summary = stats.summary(s, final, task="T", checkpoint="c.pt")
    assert summary["task"] == "T" and summary["learner_steps"] == 120
    assert summary["env_steps"] == 1000 and summary["eval/return"] == 12.345
    assert summary["throughput/env_steps_per_s"] == round(final["throughput/env_steps_per_s"], 4)
