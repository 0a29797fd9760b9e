"""Where a Sim env gets its robot server from: the ``ServerProvider`` protocol.

An env asks its provider for a *lease* on a robot server and talks to ``lease.address``. When the
server fails mid-episode the env calls ``lease.report_fault(cause)``, then ``lease.release()``
and acquires a new lease; the episode ends with ``info["final_status"] == "server_restarted"``.
A provider may therefore restart servers (a supervisor does), hand out another one, or give back
the same address - the env never needs to know.

Providers here:

* ``InProcessServerProvider`` (the default, ``envs/inprocess.py``): the robot core runs in the
  env's own process and the env calls it directly - no wire, same semantics.
* ``EmbeddedServerProvider``: starts a gRPC robot server in this process with
  ``robogym_ray.robots.server.start_robot_server`` on a free loopback port and stops it on
  release (the wire path, e.g. to compare with robo-gym's). Imported lazily, so env
  registration does not import PyBullet.
* ``StaticServerProvider``: a fixed ``host:port`` that somebody else runs; faults are only
  remembered (nothing can be restarted from here).
"""

from __future__ import annotations

import logging
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, Protocol, runtime_checkable

log = logging.getLogger(__name__)


@runtime_checkable
class ServerLease(Protocol):
    """The use of one robot server, from ``acquire`` until ``release``."""

    address: str
    """``host:port`` of the robot server."""
    token: str | None
    """Shared token for gRPC metadata ``robogym-token``, or None."""

    def report_fault(self, cause: str) -> None:
        """The server failed (``cause`` as in ``RobotServerError.cause``); it may be restarted."""

    def release(self) -> None:
        """The env is done with the server (idempotent)."""


@runtime_checkable
class ServerProvider(Protocol):
    """Hands out robot servers for ``robot`` in ``scene`` with launch-style ``options``."""

    def acquire(
        self, robot: str, scene: str | None, options: Mapping[str, str], seed: int | None
    ) -> ServerLease:
        """A lease on a server that answers GetState; raise RobotServerError if none can be had."""


@dataclass
class EmbeddedLease:
    """A robot server running in this process (owned by the lease)."""

    handle: Any
    """``robogym_ray.robots.server.RobotServerHandle``."""
    token: str | None = None
    faults: list[str] = field(default_factory=list)
    released: bool = False

    @property
    def address(self) -> str:
        return str(self.handle.address)

    def report_fault(self, cause: str) -> None:
        self.faults.append(cause)
        log.warning("embedded robot server %s faulted (%s)", self.address, cause)

    def release(self) -> None:
        if not self.released:
            self.released = True
            self.handle.stop(grace=0.0)


@dataclass(frozen=True)
class EmbeddedServerProvider:
    """Starts an in-process robot server per lease (the default of every Sim env).

    Args:
        real_time: pace the simulation against the wall clock (default: simulated time).
        host: interface to bind (loopback).
    """

    real_time: bool = False
    host: str = "127.0.0.1"

    def acquire(
        self, robot: str, scene: str | None, options: Mapping[str, str], seed: int | None
    ) -> EmbeddedLease:
        from robogym_ray.robots.server import start_robot_server  # lazy: imports PyBullet

        handle = start_robot_server(
            robot,
            scene=scene,
            seed=seed,
            options=dict(options),
            host=self.host,
            port=0,
            real_time=self.real_time,
        )
        return EmbeddedLease(handle=handle)


@dataclass
class StaticLease:
    """A server at a fixed address, run by somebody else."""

    address: str
    token: str | None = None
    faults: list[str] = field(default_factory=list)

    def report_fault(self, cause: str) -> None:
        self.faults.append(cause)
        log.warning(
            "robot server %s faulted (%s); it cannot be restarted from here", self.address, cause
        )

    def release(self) -> None:
        pass


@dataclass(frozen=True)
class StaticServerProvider:
    """Always the server at ``address`` (what ``rs_address=`` means for a Sim env)."""

    address: str
    token: str | None = None

    def acquire(
        self, robot: str, scene: str | None, options: Mapping[str, str], seed: int | None
    ) -> StaticLease:
        return StaticLease(self.address, self.token)


def default_provider() -> ServerProvider:
    """An in-process core. A supervised server is never looked up here: whoever wants one
    passes a provider, so a Sim env behaves the same in any process."""
    from robogym_ray.envs.inprocess import InProcessServerProvider

    return InProcessServerProvider()
