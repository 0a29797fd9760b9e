"""The supervisor actor on a local Ray: each of the paper's five faults injected for real.

One supervisor and one MiR100 robot-server actor are shared by the fault tests (a new actor
process costs ~1-2 s on 2 cores); each test checks that *its* cause was counted once more, that
the server came back, and that a client carries on against the (new) address.
"""

from __future__ import annotations

import os
import signal
import time
from typing import Any

import numpy as np
import pytest

from robogym_ray.errors import RobotServerError
from robogym_ray.protocol.client import Deadlines, RobotServerClient
from robogym_ray.supervision.restart_policy import RestartPolicy
from robogym_ray.supervision.server_host import ServerSpec
from robogym_ray.supervision.supervisor import SupervisorConfig

ray = pytest.importorskip("ray")
pytestmark = [pytest.mark.ray, pytest.mark.usefixtures("ray_cluster")]

CONFIG = SupervisorConfig(
    probe_interval_s=0.3,
    probe_deadline_s=0.5,
    start_timeout_s=30.0,
    restart=RestartPolicy(max_restarts=8, backoff_s=0.1, backoff_max_s=0.5),
)


@pytest.fixture(scope="module")
def supervisor(ray_cluster: None) -> Any:
    from robogym_ray.distributed.robot_actors import start_supervisor

    actor = start_supervisor(CONFIG, name="test-supervisor")
    yield actor
    ray.get(actor.shutdown.remote())
    ray.kill(actor, no_restart=True)


@pytest.fixture(scope="module")
def server(supervisor: Any) -> str:
    info = ray.get(supervisor.start_server.remote(ServerSpec("mir100", scene="empty", seed=0)))
    return str(info["id"])


def _info(supervisor: Any, sid: str) -> dict[str, Any]:
    return ray.get(supervisor.info.remote(sid))


def _wait_restarted(supervisor: Any, sid: str, generation: int, timeout: float = 20.0) -> dict:
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        info = _info(supervisor, sid)
        if info["generation"] > generation and info["state"] == "running":
            return info
        time.sleep(0.1)
    raise AssertionError(f"server {sid} not restarted within {timeout} s: {info}")


def _client_carries_on(address: str) -> None:
    with RobotServerClient(address, deadlines=Deadlines.uniform(5.0)) as client:
        client.send_action([0.1, 0.0])
        state = client.get_state()
        assert len(state.state) == 1030 and np.all(np.isfinite(state.state))


def test_process_killed_by_pid_is_a_connection_fault(supervisor: Any, server: str) -> None:
    before = _info(supervisor, server)
    _client_carries_on(before["address"])
    os.kill(before["pid"], signal.SIGKILL)
    after = _wait_restarted(supervisor, server, before["generation"])
    assert after["pid"] != before["pid"]
    assert after["restarts"].get("connection", 0) == before["restarts"].get("connection", 0) + 1
    _client_carries_on(after["address"])


@pytest.mark.parametrize(("fault", "cause"), [("hang", "hung"), ("nan", "invalid_state")])
def test_probe_detects_hung_and_nan_servers(
    supervisor: Any, server: str, fault: str, cause: str
) -> None:
    before = _info(supervisor, server)
    ray.get(supervisor.inject_fault.remote(server, fault))
    after = _wait_restarted(supervisor, server, before["generation"])
    assert after["restarts"][cause] == before["restarts"].get(cause, 0) + 1
    assert after["recoveries"][-1][0] == cause
    _client_carries_on(after["address"])


def test_call_past_its_deadline_reported_by_client(supervisor: Any, server: str) -> None:
    before = _info(supervisor, server)
    ray.get(supervisor.inject_fault.remote(server, "stall", 3.0))
    client = RobotServerClient(before["address"], deadlines=Deadlines.uniform(0.5))
    with pytest.raises(RobotServerError) as err:
        client.send_action([0.1, 0.0])
    assert err.value.cause == "deadline"
    client.close()
    after = ray.get(supervisor.report_fault.remote(server, err.value.cause, before["generation"]))
    assert after["generation"] == before["generation"] + 1
    assert after["restarts"]["deadline"] == before["restarts"].get("deadline", 0) + 1
    _client_carries_on(after["address"])


def test_manual_restart(supervisor: Any, server: str) -> None:
    before = _info(supervisor, server)
    after = ray.get(supervisor.restart.remote(server))
    assert after["generation"] == before["generation"] + 1
    assert after["restarts"]["manual"] == before["restarts"].get("manual", 0) + 1
    assert after["pid"] != before["pid"]
    _client_carries_on(after["address"])


def test_report_of_an_already_replaced_generation_is_not_restarted_twice(
    supervisor: Any, server: str
) -> None:
    before = _info(supervisor, server)
    after = ray.get(supervisor.report_fault.remote(server, "connection", before["generation"] - 1))
    assert after["generation"] == before["generation"]
    assert after["restarts"] == before["restarts"]


def test_provider_report_fault_restarts_and_next_acquire_gets_new_server(
    supervisor: Any,
) -> None:
    from robogym_ray.distributed.provider import SupervisorServerProvider
    from robogym_ray.envs.servers import ServerProvider

    provider = SupervisorServerProvider(name="test-supervisor")
    assert isinstance(provider, ServerProvider)
    lease = provider.acquire("mir100", "empty", {}, 1)
    _client_carries_on(lease.address)
    pid = _info(supervisor, lease.server_id)["pid"]
    os.kill(pid, signal.SIGKILL)
    with pytest.raises(RobotServerError) as err:
        RobotServerClient(lease.address, deadlines=Deadlines.uniform(2.0)).get_state()
    lease.report_fault(err.value.cause)
    lease.release()
    again = provider.acquire("mir100", "empty", {}, 1)
    info = _info(supervisor, again.server_id)
    assert again.server_id == lease.server_id and info["pid"] != pid
    assert again.generation > lease.generation
    assert info["restarts"] == {"connection": 1}
    _client_carries_on(again.address)
    again.release()


def test_server_failing_every_restart_is_given_up(ray_cluster: None) -> None:
    from robogym_ray.distributed.robot_actors import start_supervisor

    config = SupervisorConfig(
        probe_interval_s=0.3,
        probe_deadline_s=0.5,
        restart=RestartPolicy(max_restarts=2, backoff_s=0.1),
    )
    actor = start_supervisor(config, name="test-supervisor-give-up")
    try:
        sid = ray.get(actor.start_server.remote(ServerSpec("mir100", scene="empty")))["id"]
        ray.get(actor.inject_fault.remote(sid, "nan", None, True))
        end = time.monotonic() + 30.0
        while (info := ray.get(actor.info.remote(sid)))["state"] != "given_up":
            assert time.monotonic() < end, f"not given up: {info}"
            time.sleep(0.2)
        assert info["restarts"] == {"invalid_state": 2}
        assert "given up after 2 restarts" in info["message"]
        assert "invalid_state" in info["message"]
        assert info["address"] == ""
    finally:
        ray.get(actor.shutdown.remote())
        ray.kill(actor, no_restart=True)


def _noisy(address: str) -> bool:
    """Two readings (one action apart) of a robot told to stand still differ only if its sensors
    are noisy (or its commands biased, which the emulation also does)."""
    with RobotServerClient(address, deadlines=Deadlines.uniform(5.0)) as client:
        first = client.send_action_get_state([0.0, 0.0]).state
        second = client.send_action_get_state([0.0, 0.0]).state
    return not np.array_equal(np.asarray(first), np.asarray(second))


def test_provider_leases_emulated_robots_that_stay_emulated_after_a_restart(
    supervisor: Any,
) -> None:
    from robogym_ray.distributed.provider import SupervisorServerProvider
    from robogym_ray.robots.emulation import EmulationConfig

    emulation = EmulationConfig(laser_noise_sigma=0.05)
    emulated = SupervisorServerProvider(name="test-supervisor", emulation=emulation)
    lease = emulated.acquire("mir100", "empty", {}, 3)
    plain = SupervisorServerProvider(name="test-supervisor").acquire("mir100", "empty", {}, 3)
    try:
        assert lease.server_id != plain.server_id
        before = _info(supervisor, lease.server_id)
        assert before["emulated"] and not _info(supervisor, plain.server_id)["emulated"]
        assert _noisy(lease.address) and not _noisy(plain.address)
        os.kill(before["pid"], signal.SIGKILL)
        after = _wait_restarted(supervisor, lease.server_id, before["generation"])
        assert after["emulated"] and _noisy(after["address"])
    finally:
        lease.release()
        plain.release()
