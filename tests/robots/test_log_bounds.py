"""What a client sends is quoted in bounded form in replies and logs, and repeats are rate-limited.

Until 2026-11-23 unknown UR ``state_dict`` keys were logged in full (60 MB sent, 60 MB of log in
1.7 s). The servers run on 127.0.0.1 with real gRPC; the log is what ``caplog`` captures from them.
"""

from __future__ import annotations

import logging
from collections.abc import Iterator

import grpc
import pytest

from robogym_ray.protocol import robot_server_pb2 as pb
from robogym_ray.protocol import robot_server_pb2_grpc as pb_grpc
from robogym_ray.robots.server import (
    ERROR_METADATA_KEY,
    LogLimit,
    RobotServerHandle,
    start_robot_server,
)
from robogym_ray.text import MAX_MESSAGE_CHARS, clip_text, first_sentence, preview

LOGGER = "robogym_ray.robots.server"
JOINTS = ("base", "shoulder", "elbow", "wrist_1", "wrist_2", "wrist_3")
Q0 = (0.0, -2.5, 1.5, -1.5, -1.4, 0.0)
GOAL = {f"{j}_joint_position": q for j, q in zip(JOINTS, Q0, strict=True)}
N_KEYS, KEY_CHARS = 300, 10_000  # 3 MB of key names: under gRPC's 4 MB message limit


@pytest.fixture(scope="module")
def ur10() -> Iterator[RobotServerHandle]:
    handle = start_robot_server("ur10", seed=0, options={"rs_mode": "1object"})
    yield handle
    handle.stop()


def stub_for(address: str) -> pb_grpc.RobotServerStub:
    return pb_grpc.RobotServerStub(grpc.insecure_channel(address))


def junk_keys(tag: str) -> dict[str, float]:
    return {f"{tag}{i:04d}" + "x" * KEY_CHARS: 1.0 for i in range(N_KEYS)}


def server_lines(caplog: pytest.LogCaptureFixture) -> list[str]:
    return [r.getMessage() for r in caplog.records if r.name == LOGGER]


def test_unknown_keys_are_quoted_in_bounded_form(
    ur10: RobotServerHandle, caplog: pytest.LogCaptureFixture
) -> None:
    caplog.set_level(logging.WARNING, logger=LOGGER)
    stub = stub_for(ur10.address)
    bad = pb.State(state_dict={**GOAL, **junk_keys("junk_")})
    assert bad.ByteSize() > N_KEYS * KEY_CHARS  # 3 MB on the wire
    reply, call = stub.SetState.with_call(bad, timeout=30)
    error = dict(call.trailing_metadata() or ()).get(ERROR_METADATA_KEY, "")
    assert not reply.success
    assert error.startswith("SetState: InvalidStateError: unknown UR state_dict keys ['junk_0000")
    assert f"(+{N_KEYS - 5} more)" in error and len(error) <= MAX_MESSAGE_CHARS
    lines = server_lines(caplog)
    assert len(lines) == 1 and "unknown UR state_dict keys" in lines[0]
    assert len(lines[0]) <= MAX_MESSAGE_CHARS + 100, len(lines[0])
    # ... and the server still works.
    assert stub.SetState(pb.State(state_dict=GOAL), timeout=10).success
    assert stub.SendActionGetState(pb.Action(action=[0.0] * 6), timeout=10).success


def test_an_unknown_object_function_name_is_quoted_in_part(
    ur10: RobotServerHandle, caplog: pytest.LogCaptureFixture
) -> None:
    caplog.set_level(logging.WARNING, logger=LOGGER)
    msg = pb.State(state_dict=GOAL, string_params={"object_0_function": "w" * 1_000_000})
    reply, call = stub_for(ur10.address).SetState.with_call(msg, timeout=30)
    error = dict(call.trailing_metadata() or ()).get(ERROR_METADATA_KEY, "")
    assert not reply.success and "unknown object_0_function 'www" in error
    assert len(error) < 400 and "chars cut" in error
    assert sum(len(line) for line in server_lines(caplog)) < 400


def test_a_repeated_bad_call_is_logged_a_bounded_number_of_times(
    caplog: pytest.LogCaptureFixture,
) -> None:
    handle = start_robot_server("ur10", seed=0)  # its own server: a fresh rate limit
    caplog.set_level(logging.WARNING, logger=LOGGER)
    try:
        stub = stub_for(handle.address)
        bad = pb.State(state_dict={**GOAL, **junk_keys("again_")})
        for _ in range(30):
            assert not stub.SetState(bad, timeout=30).success
        lines = server_lines(caplog)
        assert len(lines) == LogLimit().burst  # 10 lines for 30 calls, each bounded
        assert sum(len(line) for line in lines) <= LogLimit().burst * (MAX_MESSAGE_CHARS + 100)
        assert handle.core.calls["rejected"] == 30  # every call is still answered and counted
        assert stub.SetState(pb.State(state_dict=GOAL), timeout=10).success
    finally:
        handle.stop()


def test_log_limit_counts_what_it_suppressed_and_reopens_after_the_window() -> None:
    now = [100.0]  # the limit's clock, moved by hand: no machine is too slow for the window
    limit = LogLimit(burst=2, window_s=0.2, clock=lambda: now[0])
    kind = ("SetState", "InvalidStateError")
    assert [limit.allow(kind) for _ in range(5)] == [0, 0, None, None, None]
    assert limit.allow(("SendAction", "InvalidActionError")) == 0  # kinds are counted apart
    now[0] += 0.25
    assert limit.allow(kind) == 3  # the next line says 3 were left out
    assert limit.allow(kind) == 0
    assert limit.allow(kind) is None


def test_clip_text_and_preview_bound_their_output() -> None:
    text = "a\nb" * 1_000_000
    clipped = clip_text(text)
    assert len(clipped) <= MAX_MESSAGE_CHARS and "\n" not in clipped
    assert clipped.endswith("chars cut]") and clip_text("short") == "short"
    quoted = preview(["k" * 10_000] * 1000)
    assert len(quoted) < 1000 and quoted.endswith("(+995 more)")


def test_first_sentence_of_a_paragraph_long_library_error() -> None:
    torch_like = RuntimeError("PytorchStreamReader failed. The file may be truncated.\nTrace...")
    assert first_sentence(torch_like) == "PytorchStreamReader failed"
    assert first_sentence(EOFError()) == "EOFError"  # no message: its type
    assert len(first_sentence(ValueError("x" * 5000), limit=200)) <= 200
