"""The robot server command's config and the process helpers (``robogym_ray.serve`` runs it)."""

from __future__ import annotations

import contextlib
import ipaddress
import logging
import os
import signal
import subprocess
import sys
from collections.abc import Iterator, Sequence
from dataclasses import dataclass

from robogym_ray import children
from robogym_ray.config import check_port
from robogym_ray.errors import ConfigError

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class ServeConfig:
    """What ``robogym-ray serve`` starts."""

    robot: str = "mir100"
    """Robot model: mir100, panda, fr3, ur3, ur3e, ur5, ur5e, ur10, ur10e or ur16e."""
    scene: str | None = None
    """Scene name (mir100: lab_6x8, empty; UR: empty, tabletop); default: the robot's own."""
    host: str = "127.0.0.1"
    """Interface to listen on. Loopback by default; any other interface must be asked for."""
    port: int = 0
    """TCP port; 0 picks a free one (printed on stdout)."""
    real_time: bool = False
    """Pace the simulation against the wall clock (emulating a real robot's driver)."""
    emulate_hardware: bool = False
    """Serve an emulated real robot: latency, sensor noise, dynamics differences (--emu-*)."""
    hardware: str | None = None
    """Serve the real robot through this backend of its card (fr3: franky, libfranka's client;
    pip install -e ".[franka]"); always paced by the wall clock. Needs --fci-host."""
    fci_host: str | None = None
    """With --hardware: the arm's address (a Franka's FCI: its IP, FCI enabled in Desk)."""
    dynamics_factor: float = 0.1
    """With --hardware: resets move the arm at this fraction of its velocity, acceleration
    and jerk limits, in (0, 1]; the robot's card caps it (fr3: 0.3)."""
    realtime: str = "auto"
    """With --hardware: libfranka's real-time check, enforce | ignore | auto (ignore for a
    loopback --fci-host, i.e. a simulator such as franky-sim; enforce for a real arm)."""
    seed: int | None = None
    """Seed of the robot's own randomness (sensor noise, object trajectories)."""
    token: str | None = None
    """Shared token clients must send as gRPC metadata 'robogym-token' (or ROBOGYM_RAY_TOKEN)."""
    tls_cert: str | None = None
    """PEM certificate chain: serve over TLS (with --tls-key; clients then need --tls-ca)."""
    tls_key: str | None = None
    """PEM private key of --tls-cert (unencrypted; keep it readable by this user only)."""
    option: tuple[str, ...] = ()
    """Robot options as robo-gym launch arguments, e.g. rs_mode=only_robot action_cycle_rate=20.
    Default: those of the robot's README env, a UR arm's EndEffectorPositioning (rs_mode=1object
    action_cycle_rate=10 ...); each option given replaces its own."""

    def __post_init__(self) -> None:
        check_port(self.port, "ServeConfig.port (--port)")


def parse_options(pairs: tuple[str, ...] | list[str]) -> dict[str, str]:
    """``["k=v", "k2:=v2"]`` -> dict; robo-gym's ``:=`` is accepted as well as ``=``."""
    options: dict[str, str] = {}
    for pair in pairs:
        key, sep, value = pair.replace(":=", "=", 1).partition("=")
        if not sep or not key:
            raise ConfigError(f"robot option {pair!r} is not of the form key=value")
        options[key] = value
    return options


def is_loopback(host: str) -> bool:
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host.strip("[]")).is_loopback
    except ValueError:
        return False


@contextlib.contextmanager
def serve_process(args: Sequence[str], timeout_s: float = 20.0) -> Iterator[str]:
    """``robogym-ray serve ARGS`` in a child process; yields its ``host:port``.

    The child is stopped with SIGTERM on exit (by its own handle, never by name) and killed if
    it does not stop within ``timeout_s``. Raises ConfigError if it does not start.
    """
    cmd = [sys.executable, "-m", "robogym_ray.cli", "serve", *args]
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    # The server ends with this process, however it ends (robogym_ray.children).
    proc = children.popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True,
                          env=env)  # fmt: skip
    try:
        line = proc.stdout.readline().strip() if proc.stdout else ""
        if not line.startswith("listening on "):
            raise ConfigError(f"robot server did not start ({' '.join(cmd)}): {line!r}")
        yield line.removeprefix("listening on ")
    finally:
        if proc.poll() is None:
            proc.send_signal(signal.SIGTERM)
            try:
                proc.wait(timeout=timeout_s)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()
