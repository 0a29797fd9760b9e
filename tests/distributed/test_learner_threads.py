"""The learner actor's threads: its torch threads follow the CPUs Ray gives it, with no second
setting (a real learner actor on the session's local Ray, 2 CPUs, asked for its threads); and
its stepping thread (``rate_tolerance``) in a real run."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest
import ray

from robogym_ray.distributed import remote
from tests.learner.test_service_replay import ACT, OBS, SMALL

pytestmark = [pytest.mark.ray, pytest.mark.usefixtures("ray_cluster")]


def threads_of(*cpus: float, num_threads: int = 0, **options: object) -> list[int]:
    """The torch threads of learner actors of ``cpus`` CPUs each, started together (their
    processes' start, torch's import, is most of the cost)."""
    d4pg = dataclasses.replace(SMALL, num_threads=num_threads)
    learners = [
        remote.LearnerActor.options(num_cpus=n, **options).remote(d4pg, OBS, ACT) for n in cpus
    ]
    try:
        statuses = ray.get([learner.status.remote() for learner in learners], timeout=120)
        assert all(status["device"] == "cpu" for status in statuses)
        return [int(status["threads"]) for status in statuses]
    finally:
        for learner in learners:
            ray.kill(learner)


def test_threads_are_the_actors_cpus_rounded_down() -> None:
    assert threads_of(0.5, 1.5) == [1, 1]  # the two fit the suite's 2 CPUs at once
    assert threads_of(2) == [2]


def test_a_users_omp_setting_does_not_shrink_the_learner_but_num_threads_does() -> None:
    # OMP_NUM_THREADS=1 in a user's shell reaches Ray's workers; the learner's CPUs still count.
    env = {"runtime_env": {"env_vars": {"OMP_NUM_THREADS": "1"}}}
    assert threads_of(2, **env) == [2]
    assert threads_of(2, num_threads=1) == [1]


def test_a_run_with_decoupled_stepping_keeps_its_ratio_within_the_tolerance(
    tmp_path: Path,
) -> None:
    """``rate_tolerance``: the learner actor steps on its own thread between inserts; the run
    ends with its checkpoint and its learner steps where the samples-per-insert ratio puts them,
    within the tolerance (and the transitions that warmed the replay, which earn nothing)."""
    from robogym_ray.training.run import run_training
    from tests.distributed.test_training import pendulum

    tolerance = 32
    summary = run_training(pendulum(tmp_path, "decoupled", 2_000, evaluator=False),
                           {"rate_tolerance": tolerance})  # fmt: skip
    ratio = 256.0 / 256  # the pendulum preset's samples_per_insert / batch_size
    earned_at_most = summary["env_steps"] * ratio
    earned_at_least = (summary["env_steps"] - 1_000 - 2 * 50) * ratio  # warm-up, tails
    assert earned_at_least - tolerance <= summary["learner_steps"] <= earned_at_most + tolerance
    assert Path(summary["checkpoint"]).exists()
