"""``robogym-ray serve``: a standalone robot server in the foreground."""

from __future__ import annotations

import argparse
import contextlib
import ipaddress
import logging
import os
import signal
import subprocess
import sys
import threading
from collections.abc import Iterator, Sequence
from dataclasses import dataclass

from robogym_ray.config import add_config_args, check_port, config_from_args
from robogym_ray.errors import ConfigError
from robogym_ray.robots.emulation import EmulationConfig
from robogym_ray.robots.registry import robot_card
from robogym_ray.robots.server import start_robot_server

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class ServeConfig:
    """What ``robogym-ray serve`` starts."""

    robot: str = "mir100"
    """Robot model: mir100, panda, ur3, ur3e, ur5, ur5e, ur10, ur10e or ur16e."""
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
    seed: int | None = None
    """Seed of the robot's own randomness (sensor noise, object trajectories)."""
    token: str | None = None
    """Shared token clients must send as gRPC metadata 'robogym-token' (or ROBOGYM_RAY_TOKEN)."""
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
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True,
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


def serve_defaults(
    env_id: str | None, scene: str | None, given: dict[str, str]
) -> tuple[str | None, dict[str, str]]:
    """The scene and launch options to serve: ``env_id``'s (a card's ``serve_env``) where the
    command line gives none. A given ``world_name`` stands for the scene, and a given
    ``target_mode`` for ``rs_mode`` (the launch file reads it when rs_mode is unset)."""
    if env_id is None:
        return scene, given
    from robogym_ray.envs.registration import server_spec_of  # gymnasium: only when needed

    _, env_scene, options = server_spec_of(env_id)
    if "target_mode" in given:
        options.pop("rs_mode", None)
    if scene is None and "world_name" not in given:
        scene = env_scene
    return scene, {**options, **given}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.usage = "%(prog)s [--robot NAME] [--port PORT] [--option KEY=VALUE ...] [options]"
    add_config_args(parser, ServeConfig, title="robot server")
    add_config_args(parser, EmulationConfig, prefix="emu-", title="emulated hardware (with "
                    "--emulate-hardware)")  # fmt: skip


def run(args: argparse.Namespace) -> int:
    cfg = config_from_args(ServeConfig, args)
    card = robot_card(cfg.robot)  # an unknown name: UnknownRobotError, with a "did you mean"
    token = cfg.token or os.environ.get("ROBOGYM_RAY_TOKEN") or None
    if not is_loopback(cfg.host) and token is None:
        log.warning(
            "listening on %s without a token: anyone who reaches it can move the robot", cfg.host
        )
    scene, options = serve_defaults(card.serve_env, cfg.scene, parse_options(cfg.option))
    handle = start_robot_server(
        cfg.robot,
        scene=scene,
        seed=cfg.seed,
        options=options,
        host=cfg.host,
        port=cfg.port,
        real_time=cfg.real_time,
        token=token,
        emulation=config_from_args(EmulationConfig, args) if cfg.emulate_hardware else None,
    )
    stop = threading.Event()
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda *_: stop.set())
    print(f"listening on {handle.address}", flush=True)
    stop.wait()
    handle.stop()
    print("stopped", flush=True)
    return 0
