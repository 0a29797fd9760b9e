"""A simulated robot server owned by one object, plus the fault-injection hook tests use.

``RobotServerHost`` is what a robot-server actor is (``distributed/robot_actors.py`` wraps it with
``ray.remote``): it starts ``robogym_ray.robots.server.start_robot_server`` for a ``ServerSpec``
and reports its address and process id. ``FaultInjection`` is a testing hook that makes the
running server misbehave in the ways the supervisor must notice, without touching the server code.
"""

from __future__ import annotations

import logging
import os
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from robogym_ray.robots.base import StateSnapshot
from robogym_ray.robots.emulation import EmulationConfig
from robogym_ray.robots.server import RobotServerCore, RobotServerHandle, start_robot_server

log = logging.getLogger(__name__)

FAULTS = ("hang", "nan", "stall")
"""Faults ``FaultInjection`` can make: every call blocks (a hung simulation); GetState returns
NaN; actions take ``stall_s`` longer (a call exceeds its deadline while GetState still answers)."""


@dataclass(frozen=True)
class ServerSpec:
    """Which robot server to run and where."""

    robot: str
    scene: str | None = None
    options: dict[str, str] = field(default_factory=dict)
    seed: int | None = None
    host: str = "127.0.0.1"
    """Interface to bind; ``"auto"`` = loopback on a one-node cluster, the node's IP otherwise."""
    port: int = 0
    """Port to bind (0 = any free port). If taken, any free port is used instead."""
    real_time: bool = False
    node: str | None = None
    """Node IP to place the server on (Ray); None = anywhere."""
    resources: dict[str, float] = field(default_factory=dict)
    """Custom Ray resources the server needs (e.g. ``{"gpu_node": 0.01}``) to pick its node."""
    fault: str | None = None
    """Testing hook: a fault (see ``FAULTS``) injected as soon as the server starts."""
    emulation: EmulationConfig | None = None
    """Serve an emulated real robot (noise, latency, dynamics differences) instead of the plain
    simulation: what training with domain randomisation leases."""

    def key(self) -> tuple[Any, ...]:
        """What makes two specs interchangeable for a client (host/port/fault aside)."""
        options = tuple(sorted(self.options.items()))
        return (self.robot, self.scene, options, self.real_time, self.emulation)

    def with_port(self, port: int) -> ServerSpec:
        return replace(self, port=port)


class FaultInjection:
    """Testing hook: wraps a live ``RobotServerCore``'s methods to inject faults.

    The gRPC servicer calls ``core.get_state`` / ``set_state`` / ``send_action`` (and
    ``send_action_get_state`` goes through those), so replacing them on the instance reaches every
    RPC. Never used in production paths; ``clear()`` restores normal service.
    """

    def __init__(self, core: RobotServerCore, stall_s: float = 5.0) -> None:
        self.fault: str | None = None
        self.stall_s = stall_s
        self._released = threading.Event()
        self._wrap(core)

    def inject(self, fault: str, stall_s: float | None = None) -> None:
        if fault not in FAULTS:
            raise ValueError(f"unknown fault {fault!r}; known: {', '.join(FAULTS)}")
        if stall_s is not None:
            self.stall_s = stall_s
        self._released.clear()
        self.fault = fault

    def clear(self) -> None:
        self.fault = None
        self._released.set()

    def _wrap(self, core: RobotServerCore) -> None:
        get_state, set_state, send_action = core.get_state, core.set_state, core.send_action

        def faulty_get_state() -> StateSnapshot:
            self._before(acting=False)
            snapshot = get_state()
            if self.fault == "nan":
                return StateSnapshot(
                    state=np.full_like(np.asarray(snapshot.state, dtype=float), np.nan),
                    state_dict={k: float("nan") for k in snapshot.state_dict},
                )
            return snapshot

        core.get_state = faulty_get_state  # type: ignore[method-assign]
        core.set_state = self._acting(set_state)  # type: ignore[method-assign]
        core.send_action = self._acting(send_action)  # type: ignore[method-assign]

    def _acting(self, method: Callable[..., Any]) -> Callable[..., Any]:
        def wrapped(*args: Any) -> Any:
            self._before(acting=True)
            return method(*args)

        return wrapped

    def _before(self, acting: bool) -> None:
        if self.fault == "hang":
            self._released.wait(3600.0)  # like a simulation stuck in a physics step
        elif self.fault == "stall" and acting:
            time.sleep(self.stall_s)


class RobotServerHost:
    """Runs one robot server for its lifetime (a robot-server actor's body)."""

    def __init__(self, spec: ServerSpec) -> None:
        self.spec = spec
        self.handle = self._start(spec)
        self.faults = FaultInjection(self.handle.core)
        if spec.fault:
            self.faults.inject(spec.fault)

    def _start(self, spec: ServerSpec) -> RobotServerHandle:
        host = self.bind_host(spec.host)
        kwargs = dict(
            scene=spec.scene,
            seed=spec.seed,
            options=spec.options,
            host=host,
            real_time=spec.real_time,
            emulation=spec.emulation,
        )
        try:
            return start_robot_server(spec.robot, port=spec.port, **kwargs)  # type: ignore[arg-type]
        except OSError:
            if spec.port == 0:
                raise
            # The old port is still held (e.g. by another process): any port beats no server.
            log.warning("port %d is taken; serving %s on a free port", spec.port, spec.robot)
            return start_robot_server(spec.robot, port=0, **kwargs)  # type: ignore[arg-type]

    def bind_host(self, host: str) -> str:
        """The interface to bind; the Ray edge overrides how ``"auto"`` is resolved."""
        return "127.0.0.1" if host == "auto" else host

    def info(self) -> dict[str, Any]:
        """``address``, ``host``, ``port`` and ``pid`` of the running server."""
        return {
            "address": self.handle.address,
            "host": self.handle.host,
            "port": self.handle.port,
            "pid": os.getpid(),
        }

    def ping(self) -> bool:
        return True

    def activity(self) -> int:
        """Client calls served so far that only a client makes: SetState, SendAction and
        rejected calls. GetState is left out: the supervisor's health probes are GetStates."""
        calls = self.handle.core.calls
        return calls["set"] + calls["action"] + calls["rejected"]

    def inject_fault(self, fault: str, stall_s: float | None = None) -> None:
        """Testing hook: make the server misbehave (see ``FAULTS``)."""
        self.faults.inject(fault, stall_s)

    def clear_fault(self) -> None:
        self.faults.clear()

    def stop(self) -> None:
        self.faults.clear()  # unblock hung calls so the gRPC server can stop
        self.handle.stop(grace=0.0)
