"""Robot cards: plain data without PyBullet, the limits the built robots use, launch parsing."""

from __future__ import annotations

import sys

import numpy as np
import pytest

from robogym_ray import children
from robogym_ray.envs import REAL_ENV_IDS
from robogym_ray.envs.registration import env_robot
from robogym_ray.errors import ConfigError, UnknownRobotError
from robogym_ray.realrobot.safety import SafetyConfig, safety_for, safety_for_robot
from robogym_ray.robots.card import LaunchFamily, Limits, RobotCard
from robogym_ray.robots.registry import CARDS, make_robot, robot_card
from robogym_ray.supervision.launch import launch_families, parse_launch_cmd


def test_cards_registry_and_launch_parsing_import_no_pybullet() -> None:
    code = (
        "import sys\n"
        "from robogym_ray.robots.registry import CARDS, check_options\n"
        "from robogym_ray.supervision.launch import parse_launch_cmd\n"
        "for name in CARDS: check_options(name)\n"
        "print('pybullet' in sys.modules)\n"
    )
    done = children.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=120, check=True
    )
    assert done.stdout.strip().splitlines()[-1] == "False"


def test_every_card_is_complete_and_named_by_its_registry_key() -> None:
    assert {"mir100", "ur3", "ur3e", "ur5", "ur5e", "ur10", "ur10e", "ur16e"} <= set(CARDS)
    for name, card in CARDS.items():
        assert card.name == name
        assert card.factory.startswith(f"robogym_ray.robots.{card.family}.")
        assert card.option_parser.startswith(f"robogym_ray.robots.{card.family}.")
        assert card.safety is not None and len(card.safety.low) == len(card.limits.names)
        assert card.state.length >= max((s.stop for s in card.state.slots), default=0)
        assert (card.geometry.dh is not None) == (card.kind == "arm")
        assert (card.geometry.footprint is not None) == (card.kind == "base")


def test_limits_are_symmetric_or_lower_upper() -> None:
    names = ("a", "b")
    symmetric = Limits(names=names, velocity=(1.0, 1.0), position=(1.0, 2.0))
    assert symmetric.position_range == ((-1.0, -2.0), (1.0, 2.0))
    skewed = Limits(names=names, velocity=(1.0, 1.0), lower=(-1.0, 0.0), upper=(0.5, 3.0))
    assert skewed.position_range == ((-1.0, 0.0), (0.5, 3.0))
    assert Limits(names=names, velocity=(1.0, 1.0)).position_range is None
    with pytest.raises(ValueError, match="come together"):
        Limits(names=names, velocity=(1.0, 1.0), lower=(-1.0, 0.0))
    with pytest.raises(ValueError, match="not both"):
        Limits(names=names, velocity=(1.0, 1.0), position=(1.0, 1.0), lower=(0, 0), upper=(1, 1))
    with pytest.raises(ValueError, match=r"lower > upper for \['b'\]"):
        Limits(names=names, velocity=(1.0, 1.0), lower=(-1.0, 2.0), upper=(1.0, 1.0))


def _check_base(card: RobotCard, robot) -> None:
    limits = robot.config.limits  # the drive the robot integrates with
    assert (limits.max_linear_velocity, limits.max_angular_velocity) == card.limits.velocity
    assert (limits.max_linear_acceleration, limits.max_angular_acceleration) == (
        card.limits.acceleration
    )
    from robogym_ray.robots.mir100.model import FOOTPRINT

    assert card.geometry.footprint == FOOTPRINT


def _check_arm(card: RobotCard, robot) -> None:
    client, uid = robot._world.client, robot._uid
    joints = {}
    for j in range(client.getNumJoints(uid)):
        info = client.getJointInfo(uid, j)
        joints[info[1].decode()] = info
    assert card.limits.position_range is not None
    low, high = card.limits.position_range
    for i, name in enumerate(card.limits.names):  # the URDF PyBullet loaded
        _, _, _, _, _, _, _, _, lower, upper, _, velocity, *_ = joints[name]
        assert (lower, upper) == pytest.approx((low[i], high[i]))
        assert velocity == pytest.approx(card.limits.velocity[i], rel=1e-7)
    # The controller clips every target into the card's range (symmetric or not).
    far = np.full(len(card.limits.names), 1e3)
    np.testing.assert_allclose(robot._controller.clip(-far), low)
    np.testing.assert_allclose(robot._controller.clip(far), high)
    np.testing.assert_allclose(robot._controller.max_velocity, card.limits.velocity)
    model = getattr(robot, "model", None)  # an arm that exposes its kinematic model (the UR)
    if model is not None:
        assert model.dh == card.geometry.dh


@pytest.mark.parametrize("name", sorted(CARDS))
def test_the_built_robot_uses_its_cards_limits(name: str) -> None:
    card = CARDS[name]
    robot = make_robot(name, seed=0)
    try:
        assert robot.name == name
        (_check_arm if card.kind == "arm" else _check_base)(card, robot)
        state = robot.compose(robot.read_sensors())
        assert len(state.state) == card.state.length
        assert set(state.state_dict) == set(card.state.keys)
    finally:
        robot.close()


def test_real_robot_safety_comes_from_the_card_of_the_envs_robot() -> None:
    for env_id in REAL_ENV_IDS:
        card = robot_card(env_robot(env_id))
        assert safety_for(env_id) == SafetyConfig.from_card(card)
        assert safety_for(env_id).high == card.safety.high
    assert safety_for_robot("ur5", max_step=0.1).max_step == (0.1,) * 6
    with pytest.raises(ConfigError, match="unknown env id"):
        safety_for("RoboGymRay/NoSuchTaskSim-v0")
    with pytest.raises(UnknownRobotError, match="known robots"):
        safety_for_robot("r2d2")


def _cmd(launch: LaunchFamily) -> str:
    model = f" {launch.model_argument}:={launch.model_value}" if launch.model_argument else ""
    return f"roslaunch pkg {launch.launch_file}         world_name:=empty.world{model}"


@pytest.mark.parametrize("name", sorted(CARDS))
def test_each_cards_launch_command_parses_to_that_robot(name: str) -> None:
    spec = parse_launch_cmd(_cmd(CARDS[name].launch))
    assert spec.robot == name
    assert spec.options == {"world_name": "empty.world"}  # the model argument is no option


def test_launch_families_come_from_the_cards() -> None:
    families = launch_families()
    assert set(families) == {c.launch.launch_file for c in CARDS.values()}
    ur = [c.name for c in families["ur_robot_server.launch"]]
    assert sorted(ur) == sorted(n for n, c in CARDS.items() if c.family == "ur")
    with pytest.raises(UnknownRobotError, match="ur_model:=ur7 .*known: ur3"):
        parse_launch_cmd("roslaunch ur_robot_server ur_robot_server.launch ur_model:=ur7")
    with pytest.raises(UnknownRobotError, match="known launch files"):
        parse_launch_cmd("roslaunch x nope.launch")
    # A family of one more card, as a new robot's folder would add it.
    extra = {
        **CARDS,
        "toy": RobotCard(
            name="toy",
            family="toy",
            kind="base",
            limits=CARDS["mir100"].limits,
            launch=LaunchFamily("toy.launch"),
            state=CARDS["mir100"].state,
            factory="robogym_ray.robots.toy.model:make",
            option_parser="robogym_ray.robots.toy.config:parse",
        ),
    }
    assert [c.name for c in launch_families(extra)["toy.launch"]] == ["toy"]
