"""The embedded Ray: one node on this machine, every Ray listener on loopback.

Ray 2.60 turns a node address of 127.0.0.1 into the machine's routable IP
(``ray.init(_node_ip_address=...)`` goes through ``services.resolve_ip_for_localhost``), and a
node with a routable address binds its GCS, raylet, core workers and agents on every interface
(``*:port``). With the auth these docs turn off (``RAY_AUTH_MODE=disabled``) that would let any
host on the network submit code to a training started with ``robogym-ray train``.

Ray's own switch for a node that stays on 127.0.0.1 is the one it uses by default on macOS and
Windows: ``RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER=0`` makes ``get_node_ip_address`` answer
127.0.0.1, and a node whose address is 127.0.0.1 binds loopback only. It is read once, when
``ray`` is imported, so it is set on the imported module for the ``ray.init`` call (and in the
environment the node's processes inherit). A cluster (``--address``) is untouched: its nodes
were started by ``ray start`` with the addresses their owner chose.

A second process that joins such a Ray (``robogym-ray resume-robot --ray-address 127.0.0.1:PORT``)
needs the same switch, or Ray rewrites 127.0.0.1 to the routable IP, where nothing listens, and
waits for a GCS it cannot reach: ``join_ray`` sets it when the address is loopback and the port
does not answer on the routable IP.
"""

from __future__ import annotations

import logging
import os
import socket
from collections.abc import Iterator
from contextlib import contextmanager, nullcontext
from typing import Any

import ray

from robogym_ray.errors import RayNotFoundError

log = logging.getLogger(__name__)

LOOPBACK = "127.0.0.1"
_CLUSTER_SWITCH = "RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER"
_PROBE_S = 5.0
"""How long a Ray's GCS port may take to accept a connection before it counts as absent."""


@contextmanager
def _single_node_addresses() -> Iterator[None]:
    constants = getattr(getattr(ray, "_private", None), "ray_constants", None)
    had_constant = constants is not None and hasattr(constants, "ENABLE_RAY_CLUSTER")
    saved_constant = constants.ENABLE_RAY_CLUSTER if had_constant else None
    saved_env = os.environ.get(_CLUSTER_SWITCH)
    os.environ[_CLUSTER_SWITCH] = "0"
    if had_constant:
        constants.ENABLE_RAY_CLUSTER = False
    try:
        yield
    finally:
        if had_constant:
            constants.ENABLE_RAY_CLUSTER = saved_constant
        if saved_env is None:
            os.environ.pop(_CLUSTER_SWITCH, None)
        else:
            os.environ[_CLUSTER_SWITCH] = saved_env


def start_local_ray(num_cpus: float, **init_kwargs: Any) -> str:
    """``ray.init`` a new single-node Ray listening on loopback; returns its node address.

    ``init_kwargs`` go to ``ray.init`` (``namespace``, ``_temp_dir``, ``log_to_driver`` ...);
    the dashboard stays off unless asked for. If this Ray version ignores the switch the node
    still starts, and a warning names the address it listens on.
    """
    init_kwargs.setdefault("include_dashboard", False)
    with _single_node_addresses():
        ray.init(num_cpus=num_cpus, **init_kwargs)
    address = ray.util.get_node_ip_address()
    if address != LOOPBACK:
        log.warning(
            "the embedded Ray listens on %s, not loopback (ray %s ignored %s=0): its ports "
            "are reachable from the network",
            address,
            ray.__version__,
            _CLUSTER_SWITCH,
        )
    return address


def join_ray(address: str, **init_kwargs: Any) -> None:
    """``ray.init(address=...)``, also for a loopback-only Ray that ``start_local_ray`` started.

    Raises:
        RayNotFoundError: no Ray runs there (``find_ray``), before ``ray.init`` is asked.
    """
    address = find_ray(address)
    with _single_node_addresses() if _loopback_only(address) else nullcontext():
        ray.init(address=address, **init_kwargs)


def find_ray(address: str) -> str:
    """The address of the Ray that ``join_ray(address)`` joins, checked to answer.

    ``"auto"`` is looked up as Ray does (``RAY_ADDRESS``, then the latest cluster on this machine)
    with the switch on, so that a loopback address found there stays loopback. Where none runs,
    ``ray.init`` raises a ConnectionError with a traceback, and for a port nothing listens on it
    waits about a minute: this says so in one line instead (a ``ray://`` client address is left
    to Ray).

    Raises:
        RayNotFoundError: ``"auto"`` found no Ray, or nothing accepts a connection at the
            address's port.
    """
    if address == "auto":
        services = getattr(getattr(ray, "_private", None), "services", None)
        lookup = getattr(services, "canonicalize_bootstrap_address", None)
        if lookup is None:
            return address  # another Ray version: ray.init looks it up itself
        try:
            with _single_node_addresses():
                address = lookup(address) or address
        except ConnectionError:
            raise RayNotFoundError(
                "no Ray runs on this machine (and RAY_ADDRESS is unset)"
            ) from None
    host, _, port = address.rpartition(":")
    if address.startswith("ray://") or not port.isdigit():
        return address
    try:
        with socket.create_connection((host.strip("[]"), int(port)), timeout=_PROBE_S):
            return address
    except OSError:
        raise RayNotFoundError(f"no Ray answers at {address}") from None


def _loopback_only(address: str) -> bool:
    """Whether ``address`` is a loopback GCS that does not listen on this machine's routable IP."""
    host, _, port = address.rpartition(":")
    if host.strip("[]") not in ("127.0.0.1", "localhost", "::1") or not port.isdigit():
        return False
    routable = routable_ip()
    if routable == LOOPBACK:
        return False
    try:
        with socket.create_connection((routable, int(port)), timeout=1.0):
            return False  # a Ray listening on every interface: join it the usual way
    except OSError:
        return True


def routable_ip() -> str:
    """The address this machine reaches other hosts from (127.0.0.1 without a network)."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
        try:
            # The address Ray rewrites 127.0.0.1 to is found the same way; UDP connect sends
            # nothing, it only picks the outgoing route.
            probe.connect(("8.8.8.8", 53))
            return str(probe.getsockname()[0])
        except OSError:
            return LOOPBACK
