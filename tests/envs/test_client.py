"""The robot-server client: deadlines, typed errors, messages that name the server."""

from __future__ import annotations

import socket
import threading
import time

import grpc
import numpy as np
import pytest

from robogym_ray.errors import InvalidActionError, RobotServerError
from robogym_ray.protocol import robot_server_pb2 as pb
from robogym_ray.protocol.client import Deadlines, RobotServerClient, check_action
from tests.envs.conftest import success_for

DEADLINE_S = 30.0
"""A deadline no refused connection comes near, on any machine."""


def free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return sock.getsockname()[1]


def test_round_trip(fake_server):
    state = pb.State(state=[1.0, 2.0], success=True)
    address, servicer = fake_server(lambda rpc, req, ctx: success_for(rpc, state))
    with RobotServerClient(address) as client:
        assert list(client.get_state().state) == [1.0, 2.0]
        client.set_state(pb.State(state=[3.0]))
        client.send_action([0.5, -0.5])
        assert client.send_action_get_state(np.array([0.1, 0.2])).success
    rpcs = [rpc for rpc, _ in servicer.requests]
    assert rpcs == ["GetState", "SetState", "SendAction", "SendActionGetState"]
    assert list(servicer.requests[2][1].action) == [0.5, -0.5]


def test_unreachable_server_is_a_connection_error():
    address = f"127.0.0.1:{free_port()}"
    start = time.monotonic()
    client = RobotServerClient(address, deadlines=Deadlines.uniform(DEADLINE_S))
    with client, pytest.raises(RobotServerError) as err:
        client.get_state()
    assert err.value.cause == "connection"
    assert address in str(err.value) and "GetState" in str(err.value)
    assert time.monotonic() - start < DEADLINE_S  # refused at once, not waited out


def test_slow_server_hits_the_deadline(fake_server):
    # The server answers only once released, after the call: the call's end is its deadline's
    # doing, however fast the machine is.
    release = threading.Event()

    def slow(rpc, req, ctx):
        release.wait(timeout=60)
        return success_for(rpc, pb.State(success=True))

    address, _ = fake_server(slow)
    start = time.monotonic()
    client = RobotServerClient(address, deadlines=Deadlines.uniform(0.3))
    try:
        with client, pytest.raises(RobotServerError) as err:
            client.send_action([0.0])
        assert time.monotonic() - start >= 0.3  # not before its deadline
    finally:
        release.set()
    assert err.value.cause == "deadline"
    assert "0.3 s deadline" in str(err.value) and address in str(err.value)


def test_rejection_carries_the_servers_reason(fake_server):
    def reject(rpc, req, ctx):
        ctx.set_trailing_metadata((("robogym-error", "action[1] = 9 outside [-1, 1]"),))
        return pb.Success(success=False) if rpc == "SendAction" else pb.State(success=False)

    address, _ = fake_server(reject)
    with RobotServerClient(address) as client:
        with pytest.raises(RobotServerError, match=r"outside \[-1, 1\]") as err:
            client.send_action([0.0, 9.0])
        assert err.value.cause == "rejected" and err.value.address == address
        with pytest.raises(RobotServerError, match="GetState rejected"):
            client.get_state()


def test_rejected_state_without_metadata_uses_string_params(fake_server):
    reply = pb.State(success=False, string_params={"error": "rs_mode unknown"})
    address, _ = fake_server(lambda rpc, req, ctx: reply)
    with RobotServerClient(address) as client, pytest.raises(RobotServerError, match="rs_mode"):
        client.send_action_get_state([0.0])


def test_other_grpc_status_is_named(fake_server):
    def abort(rpc, req, ctx):
        ctx.abort(grpc.StatusCode.UNIMPLEMENTED, "no SendActionGetState here")

    address, _ = fake_server(abort)
    with RobotServerClient(address) as client, pytest.raises(RobotServerError) as err:
        client.send_action_get_state([0.0])
    assert err.value.cause == "rpc" and "UNIMPLEMENTED" in str(err.value)


@pytest.mark.parametrize(
    ("action", "match"),
    [([0.0, float("nan")], r"action\[1\] = nan"), ([[0.0]], "shape"), (["a"], "numbers")],
)
def test_bad_actions_are_refused_before_sending(action, match):
    with pytest.raises(InvalidActionError, match=match):
        check_action(action)


def test_token_is_sent_as_metadata(fake_server):
    seen = {}

    def reply(rpc, req, ctx):
        seen.update(dict(ctx.invocation_metadata()))
        return pb.State(success=True)

    address, _ = fake_server(reply)
    with RobotServerClient(address, token="s3cret") as client:
        client.get_state()
    assert seen["robogym-token"] == "s3cret"
