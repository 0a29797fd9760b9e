"""The real-robot actor against ``robogym-ray serve --real-time`` standing in for the hardware.

Checks: the safety filter clips out-of-limit commands and refuses malformed ones; an error or an
emergency stop pauses the robot, which stays paused (and is never restarted - the stand-in's
process is the same one throughout) until an operator resumes it, by method or CLI.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from typing import Any

import pytest

from robogym_ray import children
from robogym_ray.realrobot.robot import RobotPausedError
from robogym_ray.realrobot.safety import (
    SafetyConfig,
    SafetyFilter,
    UnsafeCommandError,
    safety_for_robot,
)

ray = pytest.importorskip("ray")


def _serve(port: int = 0) -> tuple[subprocess.Popen[str], str]:
    proc = children.popen(
        [
            sys.executable,
            "-m",
            "robogym_ray.cli",
            "serve",
            "--robot",
            "mir100",
            "--real-time",
            "--port",
            str(port),
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.DEVNULL,
        text=True,
    )
    line = proc.stdout.readline().strip()  # type: ignore[union-attr]
    assert line.startswith("listening on "), line
    return proc, line.removeprefix("listening on ")


def _stop(proc: subprocess.Popen[str]) -> None:
    if proc.poll() is None:
        os.kill(proc.pid, signal.SIGTERM)
        proc.wait(timeout=20)


@pytest.fixture()
def hardware() -> Iterator[tuple[subprocess.Popen[str], str]]:
    proc, address = _serve()
    yield proc, address
    _stop(proc)


def _remote(method: Any, *args: Any) -> Any:
    return ray.get(method.remote(*args))


def test_safety_filter_clips_limits_and_refuses_malformed_or_jumps() -> None:
    f = SafetyFilter(SafetyConfig(low=(-1.0, -1.5), high=(1.0, 1.5), max_step=(1.5, 3.0)))
    assert f.filter([5.0, -0.5]).tolist() == [1.0, -0.5] and f.clipped == 1
    for bad in ([float("nan"), 0.0], [0.1], [0.1, 0.2, 0.3]):
        with pytest.raises(UnsafeCommandError):
            f.filter(bad)
    with pytest.raises(UnsafeCommandError, match="jumps"):
        f.filter([-1.0, 0.0])  # 2.0 from the previous 1.0
    refuse = SafetyFilter(SafetyConfig(low=(-1.0,), high=(1.0,), on_violation="refuse"))
    with pytest.raises(UnsafeCommandError, match="outside"):
        refuse.filter([1.5])
    assert refuse.refused == 1


def test_an_idle_robot_is_probed_and_pauses_when_its_server_dies() -> None:
    from robogym_ray.protocol.client import Deadlines
    from robogym_ray.realrobot.robot import RealRobot
    from robogym_ray.robots.server import start_robot_server

    server = start_robot_server("mir100")
    robot = RealRobot(
        "idle",
        server.address,
        safety_for_robot("mir100"),
        deadlines=Deadlines.fast(),
        probe_interval_s=0.1,
    )
    try:
        deadline = time.monotonic() + 10
        while robot.idle_probes < 3 and time.monotonic() < deadline:
            time.sleep(0.05)
        assert robot.idle_probes >= 3 and not robot.paused  # a live idle robot stays running
        server.stop(grace=0)
        while not robot.paused and time.monotonic() < deadline + 10:
            time.sleep(0.05)
        assert robot.paused and "GetState failed" in robot.pause_reason
        probes = robot.idle_probes
        time.sleep(0.5)
        assert robot.idle_probes == probes  # a paused robot waits for its operator
        with pytest.raises(RobotPausedError):
            robot.send_action([0.1, 0.0])
    finally:
        robot.close()
        server.stop(grace=0)
    with pytest.raises(ValueError, match="probe_interval_s"):
        RealRobot("x", server.address, safety_for_robot("mir100"), check=False, probe_interval_s=-1)


@pytest.mark.ray
@pytest.mark.usefixtures("ray_cluster")
def test_paused_robot_stays_paused_until_resumed_and_is_never_restarted(
    hardware: tuple[subprocess.Popen[str], str],
) -> None:
    from robogym_ray.distributed.robot_actors import start_supervisor
    from robogym_ray.supervision.supervisor import SupervisorConfig

    proc, address = hardware
    supervisor = start_supervisor(SupervisorConfig(probe_interval_s=0.2), name="test-real-sup")
    try:
        status = _remote(
            supervisor.join_real_robot, "mir-real", address, safety_for_robot("mir100")
        )
        assert not status["paused"]
        robot = ray.get_actor("mir-real", namespace="robogym-ray")
        assert _remote(robot.send_action, [3.0, -9.0]) == [1.0, -1.5]  # clipped, then sent
        with pytest.raises(UnsafeCommandError):
            _remote(robot.send_action, [float("inf"), 0.0])

        _remote(robot.emergency_stop, "operator pressed e-stop")
        with pytest.raises(RobotPausedError, match="resume-robot mir-real"):
            _remote(robot.send_action, [0.1, 0.0])
        time.sleep(1.0)  # several supervisor probe periods: nothing un-pauses or restarts it
        [listed] = _remote(supervisor.real_robots)
        assert listed["paused"] and listed["reason"] == "operator pressed e-stop"
        assert _remote(supervisor.status) == []  # not a supervised (restartable) server
        assert proc.poll() is None  # the same "hardware" process throughout

        assert not _remote(robot.resume)["paused"]
        assert _remote(robot.send_action, [0.1, 0.0]) == [0.1, 0.0]
        assert _remote(robot.status)["clipped"] == 1
    finally:
        ray.get(supervisor.shutdown.remote())
        ray.kill(supervisor, no_restart=True)


@pytest.mark.ray
@pytest.mark.usefixtures("ray_cluster")
def test_server_error_pauses_and_operator_resumes_from_the_cli(
    hardware: tuple[subprocess.Popen[str], str],
) -> None:
    from robogym_ray.distributed.robot_actors import start_real_robot

    proc, address = hardware
    robot = start_real_robot("mir-cli", address, safety_for_robot("mir100"))
    _stop(proc)  # the hardware's driver goes away
    with pytest.raises(Exception, match="UNAVAILABLE"):
        _remote(robot.get_state)
    assert _remote(robot.status)["paused"]
    with pytest.raises(Exception, match="stays paused"):
        _remote(robot.resume, 0.5)  # the health check fails: still paused
    assert _remote(robot.check) is False

    port = int(address.rsplit(":", 1)[1])
    proc2, _ = _serve(port)  # the operator brings the driver back
    try:
        gcs = ray.get_runtime_context().gcs_address
        out = children.run(
            [sys.executable, "-m", "robogym_ray.cli", "resume-robot", "mir-cli"]
            + ["--ray-address", gcs],
            capture_output=True,
            text=True,
            timeout=60,
        )
        assert out.returncode == 0, out.stderr[-2000:]
        assert "mir-cli at" in out.stdout and "running" in out.stdout
        assert not _remote(robot.status)["paused"]
        assert len(_remote(robot.get_state)["state"]) == 1030
    finally:
        _stop(proc2)
        ray.kill(robot, no_restart=True)
