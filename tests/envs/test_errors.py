"""Typed errors with clear messages, nothing hangs past a deadline, Sim restarts, Real does not."""

from __future__ import annotations

import threading
import time
from dataclasses import dataclass, field

import gymnasium as gym
import numpy as np
import pytest

import robogym_ray  # noqa: F401
from robogym_ray.envs.mir100_tasks import NoObstacleNavigationMir100, ObstacleAvoidanceMir100
from robogym_ray.envs.servers import EmbeddedLease, EmbeddedServerProvider, ServerProvider
from robogym_ray.envs.ur_tasks import EmptyEnvironmentUR
from robogym_ray.errors import (
    ConfigError,
    InvalidActionError,
    InvalidStateError,
    RobotServerError,
)
from robogym_ray.protocol import robot_server_pb2 as pb
from robogym_ray.protocol.client import Deadlines
from tests.envs.conftest import success_for
from tests.envs.test_client import DEADLINE_S, free_port

MIR_ROB = "RoboGymRay/ObstacleAvoidanceMir100Rob-v0"


def test_real_variant_needs_an_address():
    with pytest.raises(ConfigError, match="rs_address"):
        gym.make(MIR_ROB)


def test_unreachable_server():
    address = f"127.0.0.1:{free_port()}"
    env = gym.make(MIR_ROB, rs_address=address, deadlines=Deadlines.uniform(DEADLINE_S))
    start = time.monotonic()
    with pytest.raises(RobotServerError, match=address) as err:
        env.reset(seed=0)
    # Refused at once, not waited out.
    assert err.value.cause == "connection" and time.monotonic() - start < DEADLINE_S
    env.close()


def test_hanging_server_fails_at_the_deadline(fake_server):
    # The server answers only once released, after the call: the call's end is its deadline's
    # doing, however fast the machine is.
    release = threading.Event()

    def hang(rpc, req, ctx):
        release.wait(timeout=60)
        return success_for(rpc, pb.State(success=True))

    address, _ = fake_server(hang)
    env = gym.make(MIR_ROB, rs_address=address, deadlines=Deadlines.uniform(0.5))
    start = time.monotonic()
    try:
        with pytest.raises(RobotServerError) as err:
            env.reset(seed=0)
        assert time.monotonic() - start >= 0.5  # not before its deadline
    finally:
        release.set()
    assert err.value.cause == "deadline"
    env.close()


def test_short_mir_state_is_an_invalid_state(fake_server):
    address, _ = fake_server(
        lambda rpc, req, ctx: success_for(rpc, pb.State(state=[0.0] * 5, success=True))
    )
    env = gym.make(MIR_ROB, rs_address=address)
    with pytest.raises(InvalidStateError, match="wrong length: 5 values, expected 1030"):
        env.reset(seed=0)
    env.close()


def test_nan_laser_is_an_invalid_state(fake_server):
    state = np.zeros(1030, np.float32)
    state[8:1020] = 3.0
    state[8 + 67] = np.nan
    address, _ = fake_server(
        lambda rpc, req, ctx: success_for(rpc, pb.State(state=state, success=True))
    )
    env = gym.make(MIR_ROB, rs_address=address)
    with pytest.raises(InvalidStateError, match=r"observation\[5\] = nan outside \[0, 29\]"):
        env.reset(seed=0)
    env.close()


def test_ur_state_with_missing_keys(fake_server):
    reply = pb.State(success=True, state_dict={"base_joint_position": 0.0})
    address, _ = fake_server(lambda rpc, req, ctx: success_for(rpc, reply))
    env = EmptyEnvironmentUR(rs_address=address, real_robot=True)
    with pytest.raises(InvalidStateError, match="keys do not match rs_mode 'only_robot'"):
        env.reset(seed=0)
    env.close()


@pytest.mark.parametrize("bad", [[np.nan, 0.0], [0.0, np.inf], [0.0, 0.0, 0.0]])
def test_bad_action(bad):
    env = gym.make("RoboGymRay/NoObstacleNavigationMir100Sim-v0", disable_env_checker=True)
    env.reset(seed=0)
    with pytest.raises(InvalidActionError, match=r"not finite|shape"):
        env.step(np.array(bad, np.float32))
    env.close()


@dataclass
class CountingProvider:
    """The embedded provider, remembering its leases."""

    inner: ServerProvider = field(default_factory=EmbeddedServerProvider)
    leases: list[EmbeddedLease] = field(default_factory=list)

    def acquire(self, robot, scene, options, seed):
        lease = self.inner.acquire(robot, scene, options, seed)
        self.leases.append(lease)
        return lease


def test_sim_server_failure_ends_the_episode_and_is_replaced():
    provider = CountingProvider()
    env = ObstacleAvoidanceMir100(provider=provider, deadlines=Deadlines.uniform(2.0))
    obs, _ = env.reset(seed=0)
    env.step(np.zeros(2, np.float32))
    provider.leases[0].handle.stop(grace=0)  # the server dies
    obs2, reward, terminated, truncated, info = env.step(np.zeros(2, np.float32))
    assert (terminated, truncated, reward) == (False, True, 0.0)
    assert info["final_status"] == "server_restarted" and "UNAVAILABLE" in info["error"]
    assert provider.leases[0].faults == ["connection"] and len(provider.leases) == 2
    with pytest.raises(gym.error.ResetNeeded):
        env.step(np.zeros(2, np.float32))
    obs, _ = env.reset(seed=1)
    assert env.step(np.zeros(2, np.float32))[0].shape == (20,)
    assert env.client.address == provider.leases[1].address
    env.close()
    assert all(lease.released for lease in provider.leases)


def test_real_variant_never_restarts():
    lease = EmbeddedServerProvider().acquire("mir100", "empty", {}, 0)
    env = NoObstacleNavigationMir100(
        rs_address=lease.address, real_robot=True, deadlines=Deadlines.uniform(2.0)
    )
    env.reset(seed=0)
    lease.release()
    with pytest.raises(RobotServerError) as err:
        env.step(np.zeros(2, np.float32))
    assert err.value.cause == "connection"
    env.close()


def test_embedded_server_is_stopped_on_close():
    provider = CountingProvider()
    env = NoObstacleNavigationMir100(provider=provider)
    env.reset(seed=0)
    env.close()
    assert provider.leases[0].released
