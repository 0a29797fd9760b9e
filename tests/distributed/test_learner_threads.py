"""The learner actor's torch threads follow the CPUs Ray gives it, with no second setting: a
real learner actor on the session's local Ray (2 CPUs), asked for its threads."""

from __future__ import annotations

import dataclasses

import pytest
import ray

from robogym_ray.distributed import remote
from tests.learner.test_service_replay import ACT, OBS, SMALL

pytestmark = [pytest.mark.ray, pytest.mark.usefixtures("ray_cluster")]


def threads_of(num_cpus: float, num_threads: int = 0, **options: object) -> int:
    d4pg = dataclasses.replace(SMALL, num_threads=num_threads)
    learner = remote.LearnerActor.options(num_cpus=num_cpus, **options).remote(d4pg, OBS, ACT)
    try:
        status = ray.get(learner.status.remote(), timeout=120)
        assert status["device"] == "cpu"
        return int(status["threads"])
    finally:
        ray.kill(learner)


@pytest.mark.parametrize(("num_cpus", "threads"), [(0.5, 1), (1.5, 1), (2, 2)])
def test_threads_are_the_actors_cpus_rounded_down(num_cpus: float, threads: int) -> None:
    assert threads_of(num_cpus) == threads


def test_a_users_omp_setting_does_not_shrink_the_learner_but_num_threads_does() -> None:
    # OMP_NUM_THREADS=1 in a user's shell reaches Ray's workers; the learner's CPUs still count.
    env = {"runtime_env": {"env_vars": {"OMP_NUM_THREADS": "1"}}}
    assert threads_of(2, **env) == 2
    assert threads_of(2, num_threads=1) == 1
