"""``serve --hardware``: what is refused before anything connects to an arm, in one line."""

from __future__ import annotations

import pytest

from robogym_ray.errors import ConfigError, RobotFaultError
from robogym_ray.robots.hardware import HardwareConfig, make_hardware_robot
from robogym_ray.robots.registry import robot_card


def test_only_the_fr3_has_a_hardware_backend_and_its_card_caps_the_reset_dynamics() -> None:
    assert robot_card("fr3").hardware is not None
    assert robot_card("fr3").hardware.max_dynamics_factor == 0.3
    assert all(robot_card(n).hardware is None for n in ("panda", "ur10", "mir100"))


@pytest.mark.parametrize(
    ("robot", "config", "message"),
    [
        ("ur10", HardwareConfig("franky", "10.0.0.2"), "robot 'ur10' has no hardware backend"),
        ("fr3", HardwareConfig("libur", "10.0.0.2"), "has no hardware backend 'libur'"),
        ("fr3", HardwareConfig("franky", "10.0.0.2", 0.5), "above fr3's cap 0.3"),
    ],
)
def test_refused_before_connecting(robot: str, config: HardwareConfig, message: str) -> None:
    with pytest.raises(ConfigError, match=message):
        make_hardware_robot(robot, {}, config)


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"fci_host": ""}, "needs its address: --fci-host"),
        ({"fci_host": "10.0.0.2", "dynamics_factor": 0.0}, r"must be in \(0, 1\]"),
        ({"fci_host": "10.0.0.2", "dynamics_factor": float("nan")}, r"must be in \(0, 1\]"),
        ({"fci_host": "10.0.0.2", "realtime": "sometimes"}, "auto, enforce or ignore"),
    ],
)
def test_a_bad_hardware_config_says_what_was_wrong(kwargs: dict, message: str) -> None:
    with pytest.raises(ConfigError, match=message):
        HardwareConfig("franky", **kwargs)


def test_the_real_time_check_is_enforced_except_for_a_simulator_on_loopback() -> None:
    assert HardwareConfig("franky", "172.16.0.2").enforce_realtime
    assert not HardwareConfig("franky", "127.0.0.1").enforce_realtime
    assert HardwareConfig("franky", "127.0.0.1", realtime="enforce").enforce_realtime
    assert not HardwareConfig("franky", "172.16.0.2", realtime="ignore").enforce_realtime


def test_an_address_without_an_arm_is_one_clear_error() -> None:
    pytest.importorskip("franky")
    # Nothing listens on 127.0.0.2's FCI port: libfranka's TCP connect is refused at once.
    with pytest.raises(RobotFaultError, match="cannot connect to the arm's FCI at 127.0.0.2"):
        make_hardware_robot("fr3", {}, HardwareConfig("franky", "127.0.0.2"))
