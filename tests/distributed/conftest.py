"""A local Ray for the whole test session (tests marked ``ray`` use the ``ray_cluster`` fixture).

Started once (worker start-up dominates short tests on 2 cores), with its own short temp dir
under /tmp (Unix socket paths are limited to ~100 bytes), and shut down - never `ray stop` - at
the end of the session.
"""

from __future__ import annotations

import os
import shutil
import signal
import socket
import tempfile
import threading
from collections.abc import Callable, Iterator

import pytest


@pytest.fixture(scope="session")
def ray_cluster() -> Iterator[None]:
    ray = pytest.importorskip("ray")
    from robogym_ray.distributed.local_ray import start_local_ray

    if ray.is_initialized():  # somebody's test started it already: share it
        yield None
        return
    temp_dir = tempfile.mkdtemp(prefix="rgr", dir="/tmp")
    start_local_ray(
        2,
        namespace="robogym-ray",
        _temp_dir=temp_dir,
        logging_level="ERROR",
        log_to_driver=False,
    )
    try:
        yield None
    finally:
        ray.shutdown()
        shutil.rmtree(temp_dir, ignore_errors=True)


def free_port() -> int:
    """A TCP port nobody listens on right now (the OS's choice)."""
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


@pytest.fixture
def temp_dir() -> Iterator[str]:
    """A short folder under /tmp for a `ray start` cluster's files (Unix socket paths are
    limited to ~100 bytes)."""
    path = tempfile.mkdtemp(prefix="rgc", dir="/tmp")  # short: Unix socket paths are limited
    yield path
    shutil.rmtree(path, ignore_errors=True)


@pytest.fixture
def stop_run() -> Iterator[Callable[[], None]]:
    """Ends the test's in-process ``run_training`` as ``ray job stop`` would (SIGTERM: collection
    stops, the final checkpoint and summary are written, ``ended`` is ``stopped``), called from
    a watcher thread once the test has seen what it waits for, so a run bounded by
    ``max_wall_s`` need not run out its time. Sent once: a second SIGTERM exits at once. Until
    the test ends, a SIGTERM that comes after the run restored its handlers is dropped rather
    than ending pytest."""
    previous = signal.signal(signal.SIGTERM, lambda signum, frame: None)
    sent = threading.Event()

    def stop() -> None:
        if not sent.is_set():
            sent.set()
            os.kill(os.getpid(), signal.SIGTERM)

    try:
        yield stop
    finally:
        signal.signal(signal.SIGTERM, previous)
