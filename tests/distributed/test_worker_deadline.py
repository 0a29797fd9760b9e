"""The loop's worker deadline: a simulated worker whose call never returns (a simulation stuck
inside a physics step cannot be interrupted from its own thread) is killed, counted as a hung
restart, and its call fails like a dead worker's, so the loop replaces it."""

from __future__ import annotations

import time

import pytest

ray = pytest.importorskip("ray")

from ray.exceptions import RayActorError  # noqa: E402

from robogym_ray.training.config import TrainConfig  # noqa: E402
from robogym_ray.training.loop import TrainingLoop  # noqa: E402
from robogym_ray.training.stats import RunStats, WorkerSlot  # noqa: E402


@ray.remote(num_cpus=0.1)
class Stuck:
    def collect(self, seconds: float) -> float:
        time.sleep(seconds)  # a physics step that never ends, as far as the loop can tell
        return seconds


@pytest.mark.usefixtures("ray_cluster")
def test_a_worker_past_its_deadline_is_killed_and_counted_hung() -> None:
    loop = TrainingLoop.__new__(TrainingLoop)  # only the waiting part: no program needed
    loop.cfg, loop.stats = TrainConfig(worker_deadline_s=2.0), RunStats()
    stuck, quick = Stuck.remote(), Stuck.remote()
    # Both started first: on a busy machine starting an actor takes seconds of its own, which
    # would count towards the deadline under test.
    ray.get([stuck.collect.remote(0.0), quick.collect.remote(0.0)])
    slow_slot, quick_slot = WorkerSlot(0, stuck), WorkerSlot(1, quick)
    now = time.perf_counter()
    slow_slot.call_started = quick_slot.call_started = now
    pending = {stuck.collect.remote(3600.0): slow_slot, quick.collect.remote(0.2): quick_slot}
    first = loop._wait_watched(pending)  # the quick call, well within the deadline
    assert pending[first[0]] is quick_slot and ray.get(first[0]) == 0.2
    del pending[first[0]]
    ready = loop._wait_watched(pending)
    assert 2.0 <= time.perf_counter() - now < 30  # not before the deadline
    assert pending[ready[0]] is slow_slot
    with pytest.raises(RayActorError):
        ray.get(ready[0])
    assert loop.stats.restarts["hung"] == 1
