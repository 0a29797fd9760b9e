"""Fixtures for the robo-gym compatibility tests: the robo-gym venv and our servers."""

from __future__ import annotations

import os
import socket
import tempfile
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

from tests.compat.harness import Started, start_cli, stop
from tests.compat.robo_gym_venv import ensure_venv


@pytest.fixture(scope="session")
def robo_gym_python() -> Path:
    """Interpreter of the venv with robo-gym 2.0.1's client stack (built on first use)."""
    started = time.monotonic()
    python = ensure_venv()
    took = time.monotonic() - started
    if took > 5:
        print(f"\nrobo-gym venv ready at {python.parent.parent} after {took:.0f} s")
    return python


@pytest.fixture(scope="session")
def compat_tmp() -> Iterator[Path]:
    # Short path under /tmp: Ray puts unix sockets under RAY_TMPDIR (107-byte limit).
    with tempfile.TemporaryDirectory(prefix="rgc", dir="/tmp") as tmp:
        yield Path(tmp)


def _env(**extra: str) -> dict[str, str]:
    return {
        **os.environ,
        "RAY_AUTH_MODE": "disabled",
        "RAY_USAGE_STATS_ENABLED": "0",
        "PYTHONUNBUFFERED": "1",
        **extra,
    }


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


@pytest.fixture(scope="session")
def manager(compat_tmp: Path) -> Iterator[Started]:
    """``robogym-ray manager`` on a free port with its own local Ray."""
    ray_tmp = compat_tmp / "ray"
    ray_tmp.mkdir()
    started = start_cli(
        ["manager", "--port", str(free_port()), "--num-cpus", "1"],
        compat_tmp / "manager.log",
        timeout=120,
        env=_env(RAY_TMPDIR=str(ray_tmp), RAY_ADDRESS=""),
    )
    yield started
    stop(started.proc)


@pytest.fixture
def serve(compat_tmp: Path) -> Iterator[Callable[..., Started]]:
    """``serve(robot, *options)`` -> a running ``robogym-ray serve``; stopped afterwards."""
    running: list[Started] = []

    def start(robot: str, *options: str) -> Started:
        args = ["serve", "--robot", robot, "--port", "0"]
        if options:  # one --option with all of them: a repeated --option replaces the earlier
            args += ["--option", *options]
        log = compat_tmp / f"serve-{robot}-{len(running)}-{time.monotonic_ns()}.log"
        running.append(start_cli(args, log, timeout=60, env=_env()))
        return running[-1]

    yield start
    for started in running:
        stop(started.proc)
