"""Command handler: one-slot queue, repeat N, stop when empty, timing arithmetic."""

from __future__ import annotations

import threading

import numpy as np
import pytest

from robogym_ray.robots.command_handler import CommandHandler, CommandHandlerConfig


def make(repeat: int | None = None, action: float = 0.04, actuation: float = 0.008):
    published: list[np.ndarray | None] = []
    cfg = CommandHandlerConfig(action_cycle=action, actuation_cycle=actuation, repeat=repeat)
    return CommandHandler(cfg, published.append), published


def test_paper_defaults_give_the_expected_ticks() -> None:
    assert CommandHandlerConfig(0.1, 0.1).ticks_per_action == 1  # MiR100: 100 ms / 100 ms
    ur = CommandHandlerConfig(0.04, 0.008)  # UR10: 40 ms action / 8 ms actuation
    assert ur.ticks_per_action == 5
    assert ur.effective_repeat == 5
    assert CommandHandlerConfig(0.04, 0.008, repeat=2).effective_repeat == 2


def test_queue_of_one_ignores_commands_while_full() -> None:
    handler, published = make(repeat=3)
    assert handler.submit(np.array([1.0]))
    assert not handler.submit(np.array([2.0]))  # slot full: ignored
    assert handler.ignored == 1
    for _ in range(3):
        handler.tick()
    assert [p.tolist() for p in published] == [[1.0]] * 3  # the second command never went out
    assert handler.submit(np.array([2.0]))  # slot free again


def test_repeat_n_then_stop() -> None:
    handler, published = make(repeat=4)
    handler.submit(np.array([0.5, -0.5]))
    for _ in range(7):
        handler.tick()
    assert all(p is not None and p.tolist() == [0.5, -0.5] for p in published[:4])
    assert published[4:] == [None, None, None]  # empty slot publishes stop every tick
    assert handler.published == 4 and handler.stops == 3
    assert not handler.busy


def test_empty_slot_publishes_stop_from_the_start() -> None:
    handler, published = make()
    handler.tick()
    handler.tick()
    assert published == [None, None]


def test_clear_cancels_a_queued_command() -> None:
    handler, published = make(repeat=5)
    handler.submit(np.array([1.0]))
    handler.tick()
    handler.clear()
    handler.tick()
    assert published[0] is not None and published[1] is None


def test_submitted_command_is_copied() -> None:
    handler, published = make(repeat=1)
    cmd = np.array([1.0, 2.0])
    handler.submit(cmd)
    cmd[:] = 0.0
    handler.tick()
    assert published[0].tolist() == [1.0, 2.0]


def test_concurrent_submitters_fill_the_slot_once() -> None:
    handler, _ = make(repeat=1)
    results: list[bool] = []
    barrier = threading.Barrier(8)

    def submit(i: int) -> None:
        barrier.wait()
        results.append(handler.submit(np.array([float(i)])))

    threads = [threading.Thread(target=submit, args=(i,)) for i in range(8)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert results.count(True) == 1 and handler.ignored == 7


@pytest.mark.parametrize(
    "kwargs",
    [
        {"action_cycle": 0.0},
        {"actuation_cycle": -1.0},
        {"action_cycle": 0.01, "actuation_cycle": 0.02},
        {"repeat": 0},
    ],
)
def test_invalid_timing_is_refused(kwargs: dict) -> None:
    with pytest.raises(ValueError):
        CommandHandlerConfig(**kwargs)
