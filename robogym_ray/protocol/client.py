"""Robot-server client: robo-gym's RPCs with a deadline on every call and typed errors.

robo-gym's own client (spec a.2) raises a bare ``Exception`` or lets ``grpc.RpcError`` escape.
Ours turns every failure into a ``RobotServerError`` whose message names the server address,
the RPC and what went wrong, with a machine-readable ``cause``:

=================  ===============================================================
cause              when
=================  ===============================================================
``connection``     gRPC ``UNAVAILABLE`` (refused, reset, server gone)
``deadline``       gRPC ``DEADLINE_EXCEEDED`` (no answer within the call's deadline)
``rejected``       the server answered ``success=false``; the message carries the server's
                   reason (trailing metadata ``robogym-error`` or ``string_params["error"]``)
``unauthenticated`` gRPC ``UNAUTHENTICATED`` (missing or wrong ``robogym-token``)
``tls``            a TLS refusal (``TlsError``): the server's certificate is not signed by the
                   CA of ``tls_ca``, or the server requires TLS and the client has no CA (or
                   the other way round)
``rpc``            any other gRPC status (the status name is in the message)
=================  ===============================================================

Actions are checked before they are sent: wrong shape, NaN or inf raise ``InvalidActionError``.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import grpc
import numpy as np

from robogym_ray.errors import InvalidActionError, RobotServerError
from robogym_ray.protocol import robot_server_pb2 as pb
from robogym_ray.protocol import robot_server_pb2_grpc as pb_grpc
from robogym_ray.protocol.tls import open_channel, read_ca, tls_refusal

ERROR_METADATA_KEY = "robogym-error"
TOKEN_METADATA_KEY = "robogym-token"

_CAUSES = {
    grpc.StatusCode.UNAVAILABLE: "connection",
    grpc.StatusCode.DEADLINE_EXCEEDED: "deadline",
    grpc.StatusCode.UNAUTHENTICATED: "unauthenticated",
}


@dataclass(frozen=True)
class Deadlines:
    """Seconds each RPC may take before it fails with ``cause="deadline"``.

    The defaults are robo-gym's (spec a.2); in-process simulated servers answer in
    milliseconds, so much shorter values are fine there (see ``Deadlines.fast``).
    """

    get_state: float = 20.0
    set_state: float = 60.0
    send_action: float = 20.0
    send_action_get_state: float = 20.0

    @classmethod
    def uniform(cls, seconds: float) -> Deadlines:
        """The same deadline for every RPC."""
        return cls(seconds, seconds, seconds, seconds)

    @classmethod
    def fast(cls) -> Deadlines:
        """Deadlines for simulated servers in sim time (SetState still gets room to settle)."""
        return cls(get_state=5.0, set_state=20.0, send_action=5.0, send_action_get_state=5.0)


class RobotServerClient:
    """A client of one robot server (``host:port``), robo-gym wire protocol.

    Args:
        address: ``host:port`` of the robot server.
        deadlines: per-RPC deadlines in seconds.
        token: optional shared secret sent as gRPC metadata ``robogym-token``.
        tls_ca: the CA that signed the server's TLS certificate: a PEM file's path, or its
            bytes; None = a plain channel (robo-gym's servers and ``serve`` without
            ``--tls-cert``).
    """

    def __init__(
        self,
        address: str,
        *,
        deadlines: Deadlines | None = None,
        token: str | None = None,
        tls_ca: str | os.PathLike | bytes | None = None,
    ) -> None:
        self.address = address
        self.deadlines = deadlines or Deadlines()
        self._metadata = ((TOKEN_METADATA_KEY, token),) if token else None
        ca = read_ca(tls_ca, "tls_ca")
        self._secure = ca is not None
        # A private subchannel pool: after a server restart on the same port, a shared pool
        # would make this client wait out gRPC's reconnect backoff of an older channel.
        self._channel = open_channel(address, ca, (("grpc.use_local_subchannel_pool", 1),))
        self._stub = pb_grpc.RobotServerStub(self._channel)

    # -- robo-gym's RPCs -------------------------------------------------------------------
    def get_state(self) -> pb.State:
        """GetState: the current state message (``success`` is checked)."""
        return self._state_call("GetState", pb.Empty(), self.deadlines.get_state)

    def set_state(self, msg: pb.State) -> None:
        """SetState: reset the episode; returns once the server has applied the state."""
        reply, call = self._call("SetState", msg, self.deadlines.set_state)
        if not reply.success:
            raise self._rejected("SetState", call)

    def send_action(self, action: Sequence[float] | np.ndarray) -> None:
        """SendAction: one action for one control cycle."""
        reply, call = self._call("SendAction", _action_msg(action), self.deadlines.send_action)
        if not reply.success:
            raise self._rejected("SendAction", call)

    def send_action_get_state(self, action: Sequence[float] | np.ndarray) -> pb.State:
        """SendActionGetState: one action, then the state after it."""
        return self._state_call(
            "SendActionGetState", _action_msg(action), self.deadlines.send_action_get_state
        )

    def get_arguments(self) -> pb.Arguments | None:
        """GetArguments (robo-gym-server-modules' master, after 0.3.0.1): the server's action
        rate and modes, or None from a server without it (it answers ``UNIMPLEMENTED``, as
        robo-gym 2.0.x's servers and all of 2.1.2's but the Panda's do)."""
        return self._optional_call("GetArguments", self.deadlines.get_state)

    def recover_from_errors(self) -> bool:
        """RecoverFromErrors (ours): a hardware server clears its arm's errors. False from a
        server without it (robo-gym's, which answer ``UNIMPLEMENTED``); a refusal (the arm
        still faulted, its controller unreachable) raises RobotServerError."""
        return self._optional_call("RecoverFromErrors", self.deadlines.set_state) is not None

    def _optional_call(self, rpc: str, deadline: float) -> Any:
        """An RPC that not every robot server has (``Empty`` in): its reply, or None where the
        server answers ``UNIMPLEMENTED``; ``success=false`` raises as any refusal does."""
        try:
            reply, call = self._call(rpc, pb.Empty(), deadline)
        except RobotServerError as exc:
            if exc.cause == "rpc" and "UNIMPLEMENTED" in str(exc):
                return None
            raise
        if not reply.success:
            raise self._rejected(rpc, call)
        return reply

    def close(self) -> None:
        self._channel.close()

    def __enter__(self) -> RobotServerClient:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def __repr__(self) -> str:
        return f"RobotServerClient({self.address!r})"

    # -- internals -------------------------------------------------------------------------
    def _state_call(self, rpc: str, request: Any, deadline: float) -> pb.State:
        reply, call = self._call(rpc, request, deadline)
        if not reply.success:
            raise self._rejected(rpc, call, reply.string_params.get("error", ""))
        return reply

    def _call(self, rpc: str, request: Any, deadline: float) -> tuple[Any, grpc.Call]:
        method = getattr(self._stub, rpc)
        try:
            return method.with_call(request, timeout=deadline, metadata=self._metadata)
        except grpc.RpcError as exc:
            code = exc.code() if isinstance(exc, grpc.Call) else grpc.StatusCode.UNKNOWN
            details = exc.details() if isinstance(exc, grpc.Call) else str(exc)
            cause = _CAUSES.get(code, "rpc")
            if cause == "deadline":
                raise deadline_error(rpc, deadline, self.address) from None
            refused = (
                tls_refusal(self.address, details, self._secure) if cause == "connection" else None
            )
            if refused is not None:
                raise refused from None
            raise RobotServerError(
                f"{rpc} failed: {code.name}: {details}", address=self.address, cause=cause
            ) from None

    def _rejected(self, rpc: str, call: grpc.Call, fallback: str = "") -> RobotServerError:
        reason = _trailing(call, ERROR_METADATA_KEY) or fallback or "no reason given"
        return RobotServerError(
            f"{rpc} rejected (success=false): {reason}", address=self.address, cause="rejected"
        )


def deadline_error(rpc: str, deadline: float, address: str) -> RobotServerError:
    """The error of a call not answered within its deadline (gRPC or in-process)."""
    return RobotServerError(
        f"{rpc} failed: DEADLINE_EXCEEDED: no answer within the {deadline:g} s deadline",
        address=address,
        cause="deadline",
    )


def _trailing(call: grpc.Call, key: str) -> str:
    for item_key, value in call.trailing_metadata() or ():
        if item_key == key:
            return value if isinstance(value, str) else value.decode("ascii", "replace")
    return ""


def check_action(action: Sequence[float] | np.ndarray, size: int | None = None) -> np.ndarray:
    """``action`` as a finite float64 vector (of length ``size``), else InvalidActionError."""
    try:
        vec = np.asarray(action, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise InvalidActionError(f"action is not a list of numbers: {exc}") from None
    if vec.ndim != 1 or (size is not None and vec.shape[0] != size):
        want = f"({size},)" if size is not None else "a flat vector"
        raise InvalidActionError(f"action has shape {vec.shape}, expected {want}")
    bad = np.flatnonzero(~np.isfinite(vec))
    if bad.size:
        i = int(bad[0])
        raise InvalidActionError(
            f"action[{i}] = {vec[i]} is not finite (NaN/inf in {bad.size} of {vec.size} values)"
        )
    return vec


def _action_msg(action: Sequence[float] | np.ndarray) -> pb.Action:
    return pb.Action(action=check_action(action).astype(np.float32).tolist())
