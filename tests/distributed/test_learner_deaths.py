"""One learner death is one ``faults/learner_failures``, however many calls it fails: a real
learner actor (Ray restarts it), killed by its pid with several calls in flight."""

from __future__ import annotations

import os
import signal
import time
from pathlib import Path

import pytest
import ray
from ray.exceptions import ActorUnavailableError, RayActorError

from robogym_ray.distributed import remote
from robogym_ray.training.learner_deaths import LearnerDeaths
from tests.learner.test_service_replay import ACT, OBS, SMALL, batch

pytestmark = [pytest.mark.ray, pytest.mark.usefixtures("ray_cluster")]


def kill_with_calls_in_flight(learner: ray.actor.ActorHandle, calls: int) -> int:
    """SIGKILL the learner while ``calls`` long ``train`` calls wait on it; all of them fail.
    Returns how many failed."""
    pid = ray.get(learner.ping.remote())
    refs = [learner.train.remote(100_000) for _ in range(calls)]  # minutes each: still running
    os.kill(pid, signal.SIGKILL)
    failed = 0
    for ref in refs:
        with pytest.raises(RayActorError):
            ray.get(ref, timeout=120)
        failed += 1
    return failed


def add_when_back(learner: ray.actor.ActorHandle) -> int:
    """The pid an ``add`` returns from, once the restarting learner takes calls again."""
    deadline = time.monotonic() + 120
    while True:
        try:
            return int(ray.get(learner.add.remote(batch(10, 2)), timeout=120)["pid"])
        except ActorUnavailableError:  # sent while Ray still thought it the old one
            assert time.monotonic() < deadline
            time.sleep(0.2)


def test_one_learner_death_is_one_failure_however_many_calls_fail(tmp_path: Path) -> None:
    learner = remote.LearnerActor.options(num_cpus=0.1, max_restarts=3, max_task_retries=0).remote(
        SMALL, OBS, ACT, checkpoint_dir=str(tmp_path), checkpoint_every=0
    )
    try:
        ray.get(learner.add.remote(batch(100, 0)))  # above min_replay_size: train() can step
        deaths = LearnerDeaths(learner)
        first = deaths.pid
        assert kill_with_calls_in_flight(learner, 4) == 4
        counted = [deaths.call_failed() for _ in range(4)]  # what the loop sees: 4 failures
        assert counted == [True, False, False, False] and deaths.count == 1
        assert deaths.pid != first  # the restarted learner's
        # A later call that fails because its sender died is no learner death either.
        assert not deaths.call_failed() and deaths.count == 1
        # A late answer from the dead process (its call was queued behind a failed one) is
        # neither a death nor the learner's pid now.
        second = deaths.pid
        deaths.answered(first)
        assert deaths.count == 1 and deaths.pid == second
        # A second death counts again, also when only a returned call reveals it.
        ray.get(learner.add.remote(batch(100, 1)))
        assert kill_with_calls_in_flight(learner, 2) == 2
        pid = add_when_back(learner)
        deaths.answered(pid)
        assert deaths.count == 2
        assert [deaths.call_failed() for _ in range(2)] == [False, False] and deaths.count == 2
    finally:
        ray.kill(learner)
