"""Suite-wide settings (Ray's CLI and the embedded Ray agree on authentication) and fixtures."""

from __future__ import annotations

import os
import shutil
import subprocess
from collections.abc import Iterator
from typing import Any

import grpc
import pytest
import ray

from robogym_ray import children
from robogym_ray.protocol import server_manager_pb2_grpc as sm_grpc
from robogym_ray.supervision.manager_service import serve_manager
from robogym_ray.supervision.spawners import InProcessSpawner
from robogym_ray.supervision.supervisor import Supervisor, SupervisorConfig

# Ray 2.60 enables token auth by default; `ray start` / `ray job submit` in the tests and the
# embedded `ray.init` must see the same mode, so the whole suite runs with it disabled.
os.environ.setdefault("RAY_AUTH_MODE", "disabled")
# Keep Ray's usage-stats prompt and dashboard out of test runs (no network here anyway).
os.environ.setdefault("RAY_USAGE_STATS_ENABLED", "0")


@pytest.fixture
def ray_must_not_start(monkeypatch: pytest.MonkeyPatch) -> None:
    """The command under test must refuse its input before it starts Ray. In the whole suite a
    Ray is up already (tests/distributed share one) and a command would just join it, so Ray
    is made to look absent, as in the fresh process a user's command runs in, and starting it
    fails the test."""

    def tripwire(*args: object, **kwargs: object) -> None:
        pytest.fail("the command started Ray before it refused its input")

    monkeypatch.setattr(ray, "is_initialized", lambda: False)
    monkeypatch.setattr(ray, "init", tripwire)


@pytest.fixture(scope="session")
def x_display() -> Iterator[str]:
    """A real X server (Xvfb) for human-mode rendering; skipped where none can be started."""
    binary = shutil.which("Xvfb")
    if binary is None:
        pytest.skip("no Xvfb on this machine (Debian: apt-get install xvfb; .ci/run installs it)")
    read, write = os.pipe()
    proc = children.popen(
        [binary, "-displayfd", str(write), "-screen", "0", "800x600x24", "-nolisten", "tcp"],
        pass_fds=(write,),
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    os.close(write)
    with os.fdopen(read) as pipe:
        number = pipe.readline().strip()  # Xvfb writes its display number once it is ready
    if not number:
        proc.kill()
        pytest.skip("Xvfb did not start")
    yield f":{number}"
    proc.terminate()
    proc.wait(timeout=10)


@pytest.fixture
def inprocess_manager() -> Iterator[Any]:
    """A ServerManager stub for an in-process Supervisor (servers in this process, no Ray).

    Not named ``manager``: tests/compat has a session fixture of that name (a CLI manager)."""
    sup = Supervisor(SupervisorConfig(probe_interval_s=0), InProcessSpawner())
    server, port = serve_manager(sup, "127.0.0.1", 0)
    channel = grpc.insecure_channel(f"127.0.0.1:{port}")
    yield sm_grpc.ServerManagerStub(channel)
    channel.close()
    server.stop(grace=None)
    sup.shutdown()
