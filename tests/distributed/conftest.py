"""A local Ray for the whole test session (tests marked ``ray`` use the ``ray_cluster`` fixture).

Started once (worker start-up dominates short tests on 2 cores), with its own short temp dir
under /tmp (Unix socket paths are limited to ~100 bytes), and shut down - never `ray stop` - at
the end of the session.
"""

from __future__ import annotations

import shutil
import socket
import tempfile
from collections.abc import Iterator

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
