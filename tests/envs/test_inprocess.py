"""The in-process path against the gRPC path: same states, same errors; faults rebuilt and
counted, and no n-step transition spans one."""

from __future__ import annotations

import re
from typing import Any

import gymnasium as gym
import numpy as np
import pytest

import robogym_ray  # noqa: F401 - registers the ids
from robogym_ray.envs.inprocess import InProcessClient, InProcessServerProvider
from robogym_ray.envs.servers import EmbeddedServerProvider
from robogym_ray.errors import RobotServerError
from robogym_ray.experience.rollout import RolloutWorker
from robogym_ray.learner.config import D4PGConfig
from robogym_ray.protocol import robot_server_pb2 as pb
from robogym_ray.protocol.client import Deadlines
from robogym_ray.supervision.server_host import FaultInjection

NAV = "RoboGymRay/NoObstacleNavigationMir100Sim-v0"
UR = "RoboGymRay/EndEffectorPositioningRoboGymUR10Sim-v0"


def wire_bytes(msg: pb.State) -> bytes:
    """A state message as bytes (map keys sorted: protobuf leaves their order open)."""
    return msg.SerializeToString(deterministic=True)


def episode(env_id: str, provider: Any, seed: int, steps: int) -> list[tuple[Any, ...]]:
    """Every state message, observation, reward and end of a seeded episode with seeded
    random actions."""
    env = gym.make(env_id, provider=provider)
    rng = np.random.default_rng(seed)
    try:
        obs, _ = env.reset(seed=seed)
        out: list[tuple[Any, ...]] = [(wire_bytes(env.unwrapped._last_msg), obs)]
        for _ in range(steps):
            action = rng.uniform(-1, 1, env.action_space.shape)
            obs, reward, terminated, truncated, info = env.step(action)
            msg = wire_bytes(env.unwrapped._last_msg)
            out.append((msg, obs, reward, terminated, truncated, info.get("final_status")))
            if terminated or truncated:
                break
        return out
    finally:
        env.close()


@pytest.mark.parametrize("env_id", [NAV, UR])
def test_a_seeded_episode_is_the_same_in_process_and_over_grpc(env_id: str) -> None:
    inproc = episode(env_id, InProcessServerProvider(), seed=5, steps=120)
    wire = episode(env_id, EmbeddedServerProvider(), seed=5, steps=120)
    assert len(inproc) == len(wire) > 20
    for i, (a, b) in enumerate(zip(inproc, wire, strict=True)):
        assert a[0] == b[0], f"state message of step {i} differs"  # byte for byte
        np.testing.assert_array_equal(a[1], b[1])
        assert a[2:] == b[2:], f"step {i}: {a[2:]} != {b[2:]}"


def test_a_plain_make_runs_in_process() -> None:
    env = gym.make(NAV)
    env.reset(seed=0)
    assert isinstance(env.unwrapped.client, InProcessClient)
    env.close()


def refusal(env_id: str, provider: Any, bad: pb.State) -> str:
    env = gym.make(env_id, provider=provider)
    try:
        env.reset(seed=1)
        before = wire_bytes(env.unwrapped.client.get_state())
        with pytest.raises(RobotServerError) as info:
            env.unwrapped.client.set_state(bad)
        assert info.value.cause == "rejected"
        assert wire_bytes(env.unwrapped.client.get_state()) == before  # untouched
        return re.sub(r"inprocess:[\w#]+|127\.0\.0\.1:\d+", "ADDRESS", str(info.value))
    finally:
        env.close()


@pytest.mark.parametrize(
    ("env_id", "bad"),
    [
        (NAV, pb.State(state=[0.0, 0.0, float("nan")])),
        (NAV, pb.State(state=[1.0] * 7)),
        (UR, pb.State(state=[0.0] * 3, float_params={"nonsense": 1.0})),
    ],
)
def test_a_refused_set_state_reads_the_same_both_ways(env_id: str, bad: pb.State) -> None:
    assert refusal(env_id, InProcessServerProvider(), bad) == refusal(
        env_id, EmbeddedServerProvider(), bad
    )


def test_bad_actions_are_refused_before_the_core_both_ways() -> None:
    env = gym.make(NAV)
    env.reset(seed=0)
    client = env.unwrapped.client
    for action in ([0.0, float("inf")], [[0.0, 0.0]], ["x", 1]):
        with pytest.raises(ValueError, match="action"):
            client.send_action(action)
    assert client.core.calls["action"] == 0
    env.close()


def worker(provider: InProcessServerProvider, **env_kwargs: Any) -> RolloutWorker:
    def make_env() -> gym.Env:
        return gym.make(NAV, provider=provider, **env_kwargs)

    return RolloutWorker(make_env, D4PGConfig(n_step=5), seed=3, num_envs=2)


def inject(worker: RolloutWorker, k: int, fault: str, stall_s: float | None = None) -> None:
    FaultInjection(worker.slots[k].env.unwrapped.lease.core).inject(fault, stall_s)


@pytest.mark.parametrize(
    ("fault", "cause", "kwargs"),
    [
        ("nan", "invalid_state", {}),
        ("stall", "deadline", {"deadlines": Deadlines.uniform(0.3)}),
    ],
)
def test_a_faulty_in_process_sim_is_rebuilt_counted_and_no_transition_spans_it(
    fault: str, cause: str, kwargs: dict[str, Any]
) -> None:
    provider = InProcessServerProvider()
    w = worker(provider, **kwargs)
    w.collect(40)  # healthy: both envs step
    faulty = w.slots[1].env.unwrapped
    old_core, pending = faulty.lease.core, len(w.slots[1].nstep)
    inject(w, 1, fault, stall_s=0.5)
    result = w.collect(2)  # one round: env 1's step hits the fault
    assert [e.final_status for e in result.episodes] == ["server_restarted"]
    assert result.faults == {cause: 1}
    assert provider.restarts[cause] == 1
    assert result.dropped == pending + 1  # the open window and the faulted step
    # Only env 0's step completed a transition; env 1's window was thrown away.
    assert result.transitions <= 1
    assert faulty.lease.core is not old_core  # a fresh core
    after = w.collect(40)
    assert after.steps >= 40 and not after.faults
    w.close()


def test_an_exception_inside_the_sim_is_a_refusal_and_a_rebuild() -> None:
    provider = InProcessServerProvider()
    w = worker(provider)
    core = w.slots[0].env.unwrapped.lease.core

    def broken(*_: Any) -> None:
        raise RuntimeError("physics exploded")

    core.robot.advance = broken
    result = w.collect(2)
    assert result.faults == {"rejected": 1}
    assert provider.restarts["other"] == 1
    assert [e.final_status for e in result.episodes] == ["server_restarted"]
    w.close()


def test_a_sim_that_keeps_failing_is_given_up() -> None:
    from robogym_ray.supervision.restart_policy import RestartPolicy

    provider = InProcessServerProvider(restart=RestartPolicy(max_restarts=1, backoff_s=0.0))
    env = gym.make(NAV, provider=provider)
    env.reset(seed=0)
    FaultInjection(env.unwrapped.lease.core).inject("nan")
    _, _, _, truncated, info = env.step(np.zeros(2))
    assert truncated and info["fault"] == "invalid_state"  # the first fault: rebuilt
    env.reset(seed=1)
    FaultInjection(env.unwrapped.lease.core).inject("nan")
    _, _, _, truncated, info = env.step(np.zeros(2))  # the second, past the limit
    assert "given up" in info["restart_error"]
    with pytest.raises(RobotServerError, match="given up"):
        env.reset(seed=2)
    env.close()
