"""State buffer: groups update independently; snapshots are consistent under concurrency."""

from __future__ import annotations

import threading

import numpy as np

from robogym_ray.robots.state_buffer import StateBuffer


def test_groups_update_independently() -> None:
    buf = StateBuffer()
    buf.update(pose=[1.0, 2.0, 3.0], scan=np.zeros(4))
    buf.update(scan=np.ones(4))
    version, groups = buf.snapshot()
    assert version == 2
    assert groups["pose"].tolist() == [1.0, 2.0, 3.0]
    assert groups["scan"].tolist() == [1.0] * 4
    assert "pose" in buf and "missing" not in buf


def test_snapshot_is_a_copy() -> None:
    buf = StateBuffer()
    buf.update(a=[1.0])
    _, groups = buf.snapshot()
    groups["a"][0] = 99.0
    assert buf.snapshot()[1]["a"][0] == 1.0


def test_readers_never_see_half_an_update() -> None:
    """A writer updates two groups together with the same counter; readers must never mix them."""
    buf = StateBuffer()
    buf.update(a=[0.0] * 100, b=[0.0] * 100)
    stop = threading.Event()

    def writer() -> None:
        i = 0
        while not stop.is_set():
            i += 1
            buf.update(a=np.full(100, i, float), b=np.full(100, i, float))

    mixed = 0
    t = threading.Thread(target=writer)
    t.start()
    try:
        for _ in range(3000):
            _, g = buf.snapshot()
            if not (np.all(g["a"] == g["a"][0]) and g["a"][0] == g["b"][0]):
                mixed += 1
    finally:
        stop.set()
        t.join()
    assert mixed == 0
