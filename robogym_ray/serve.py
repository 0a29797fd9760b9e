"""``robogym-ray serve``: a standalone robot server in the foreground.

Above both ``robots/`` (the server, its config) and ``envs/``: a plain ``serve --robot NAME``
serves what the env its card names (``serve_env``) expects, read from that env's own spec.
"""

from __future__ import annotations

import argparse
import logging
import os

from robogym_ray.config import add_config_args, config_from_args
from robogym_ray.errors import ConfigError
from robogym_ray.foreground import StopSignals
from robogym_ray.protocol.tls import server_tls
from robogym_ray.robots.emulation import EmulationConfig
from robogym_ray.robots.hardware import HardwareConfig
from robogym_ray.robots.registry import robot_card
from robogym_ray.robots.serve import ServeConfig, is_loopback, parse_options
from robogym_ray.robots.server import start_robot_server

log = logging.getLogger(__name__)


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
    tls = server_tls(cfg.tls_cert, cfg.tls_key)  # read and checked before the robot is built
    card = robot_card(cfg.robot)  # an unknown name: UnknownRobotError, with a "did you mean"
    token = cfg.token or os.environ.get("ROBOGYM_RAY_TOKEN") or None
    if not is_loopback(cfg.host) and token is None:
        log.warning(
            "listening on %s without a token: anyone who reaches it can move the robot", cfg.host
        )
    elif not is_loopback(cfg.host) and tls is None:
        log.warning("listening on %s without TLS: the token travels in clear (--tls-cert, "
                    "--tls-key)", cfg.host)  # fmt: skip
    hardware = None
    if cfg.hardware is not None:  # checked before anything connects to the arm
        hardware = HardwareConfig(
            cfg.hardware, cfg.fci_host or "", cfg.dynamics_factor, cfg.realtime
        )
    elif cfg.fci_host is not None:
        raise ConfigError("--fci-host is the address of a real arm: give --hardware too")
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
        tls=tls,
        hardware=hardware,
        emulation=config_from_args(EmulationConfig, args, "emu-") if cfg.emulate_hardware else None,
    )
    stop = StopSignals()
    print(f"listening on {handle.address}", flush=True)
    stop.wait()
    handle.stop()
    print("stopped", flush=True)
    return 0
