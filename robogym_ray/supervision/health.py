"""Health checks of a robot server: one GetState with a short deadline, and a look at the state.

Plain functions over ``robogym_ray.protocol.client.RobotServerClient``; the supervisor probes its
servers with ``probe`` and waits for a new one with ``wait_ready`` (robo-gym's readiness rule:
GetState answers ``success=true`` with ``len(state) > 1``, spec b.3).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

from robogym_ray.errors import RobotServerError
from robogym_ray.protocol import robot_server_pb2 as pb
from robogym_ray.protocol.client import Deadlines, RobotServerClient
from robogym_ray.supervision.restart_policy import FaultCause


@dataclass(frozen=True)
class Health:
    """The outcome of one probe."""

    fault: FaultCause | None
    """None: healthy."""
    detail: str = ""
    latency_s: float = 0.0


def check_state(msg: pb.State, limit: float) -> str | None:
    """Why ``msg`` is not a valid state (NaN/inf, beyond ``limit``, too short), or None."""
    if len(msg.state) <= 1:
        return f"state has {len(msg.state)} values, expected more than 1"
    groups = (("state", list(msg.state)), ("state_dict", list(msg.state_dict.values())))
    for where, values in groups:
        for i, value in enumerate(values):
            if not math.isfinite(value) or abs(value) > limit:
                return f"{where} value #{i} = {value} is outside [-{limit:g}, {limit:g}]"
    return None


def probe(address: str, deadline_s: float, limit: float, token: str | None = None) -> Health:
    """GetState once with ``deadline_s``; classify what went wrong, if anything.

    No answer in time means a hung simulation (``HUNG``), not a client's ``DEADLINE``: the probe
    asks for nothing but a buffered snapshot, which a healthy server answers in microseconds.
    """
    start = time.monotonic()
    with RobotServerClient(address, deadlines=Deadlines.uniform(deadline_s), token=token) as c:
        try:
            msg = c.get_state()
        except RobotServerError as exc:
            cause = {
                "connection": FaultCause.CONNECTION,
                "deadline": FaultCause.HUNG,
                "rejected": FaultCause.INVALID_STATE,
            }.get(exc.cause, FaultCause.CONNECTION)
            return Health(cause, str(exc), time.monotonic() - start)
    problem = check_state(msg, limit)
    latency = time.monotonic() - start
    if problem:
        return Health(FaultCause.INVALID_STATE, f"{address}: {problem}", latency)
    return Health(None, "", latency)


def wait_ready(
    address: str, timeout_s: float, deadline_s: float, limit: float, token: str | None = None
) -> Health:
    """Probe until healthy or ``timeout_s`` passes; returns the last probe's outcome.

    A server that answers but with an invalid state is not retried: it will not get better.
    """
    end = time.monotonic() + timeout_s
    while True:
        health = probe(address, deadline_s, limit, token)
        if health.fault in (None, FaultCause.INVALID_STATE) or time.monotonic() >= end:
            return health
        time.sleep(0.05)
