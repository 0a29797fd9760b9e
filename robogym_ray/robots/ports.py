"""Exclusive TCP ports for our gRPC servers (robot servers and the server manager).

One address, one server: with gRPC's default SO_REUSEPORT a second server on a held port binds
too and clients land on either, so with real robots a command could reach the wrong robot.
"""

from __future__ import annotations

import errno
import os
import socket
from collections.abc import Sequence
from concurrent import futures

import grpc

from robogym_ray.errors import BindError, PortInUseError

EXCLUSIVE_PORT = ("grpc.so_reuseport", 0)
"""gRPC server option: bind without SO_REUSEPORT. gRPC sets it by default, so a second server
on a port a first one listens on binds too and the kernel spreads new connections over both:
clients of one address would reach two robots."""


def grpc_server(
    max_workers: int, interceptors: Sequence[grpc.ServerInterceptor] = ()
) -> grpc.Server:
    """A ``grpc.server`` whose ports are its own (``EXCLUSIVE_PORT``); bind it with ``listen``."""
    return grpc.server(
        futures.ThreadPoolExecutor(max_workers=max_workers),
        interceptors=list(interceptors),
        options=[EXCLUSIVE_PORT],
    )


def check_port_free(host: str, port: int, what: str) -> None:
    """Raise PortInUseError if ``host:port`` is held (listened on or bound) by anything.

    gRPC reports a failed bind as a bare RuntimeError after its C core has logged the reason on
    stderr; probing first gives one line naming the port, before a robot is built or Ray is
    started. The probe binds as gRPC does - SO_REUSEADDR, so connections a stopped server left in
    TIME_WAIT are no conflict (a restart may reuse its port) - but never with SO_REUSEPORT, so
    any listener conflicts. Port 0 (a free one) always passes.

    Raises:
        PortInUseError: the port is held.
        BindError: no address of ``host`` can be bound (not this machine's, no permission).
    """
    if port == 0:
        return
    bare = host.strip("[]")
    try:
        addresses = socket.getaddrinfo(bare, port, type=socket.SOCK_STREAM, flags=socket.AI_PASSIVE)
    except socket.gaierror as exc:
        raise BindError(
            f"{what} {port}: cannot resolve host {host!r} ({exc.strerror})", host=host, port=port
        ) from None
    failures: list[OSError] = []
    for family, kind, proto, _, sockaddr in addresses:
        with socket.socket(family, kind, proto) as probe:
            if os.name == "posix":  # on Windows SO_REUSEADDR would let the probe steal a port
                probe.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
            try:
                probe.bind(sockaddr)
            except OSError as exc:
                if exc.errno == errno.EADDRINUSE:
                    raise port_in_use(host, port, what) from None
                failures.append(exc)
    # gRPC serves if any resolved address binds (``localhost`` without IPv6 still works).
    if failures and len(failures) == len(addresses):
        raise BindError(
            f"{what} {port}: cannot listen on {host} ({failures[0].strerror})",
            host=host,
            port=port,
        )


def port_in_use(host: str, port: int, what: str) -> PortInUseError:
    return PortInUseError(
        f"{what} {port} on {host} is already in use by another server or program; "
        "choose another port (0 picks a free one)",
        host=host,
        port=port,
    )


def listen(
    server: grpc.Server,
    host: str,
    port: int,
    what: str,
    credentials: grpc.ServerCredentials | None = None,
) -> int:
    """Bind ``server`` (made by ``grpc_server``) to ``host:port``; returns the bound port.

    ``credentials`` (``protocol.tls.ServerTls.credentials()``) make it a TLS port; without,
    a plain one.

    Raises:
        PortInUseError: the port is held (by another server of ours or any other program).
        BindError: it cannot be bound for another reason.
    """
    check_port_free(host, port, what)
    address = f"[{host}]:{port}" if ":" in host else f"{host}:{port}"
    try:
        if credentials is None:
            bound = server.add_insecure_port(address)
        else:
            bound = server.add_secure_port(address, credentials)
    except RuntimeError:  # grpcio >= 1.5x raises where older versions returned 0
        bound = 0
    if bound == 0:
        # Taken since the probe (a race), or a failure the probe cannot see: probe again to say
        # which.
        check_port_free(host, port, what)
        raise BindError(f"{what} {port}: cannot listen on {host}", host=host, port=port)
    return bound
