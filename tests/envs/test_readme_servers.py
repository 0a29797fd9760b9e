"""The README's robot servers answer the README's envs with no extra option; a server in another
mode is refused with the ``--option`` it needs."""

from __future__ import annotations

import gymnasium as gym
import pytest

from robogym_ray.envs.registration import server_spec_of
from robogym_ray.envs.ur_tasks import EndEffectorPositioningUR
from robogym_ray.errors import ConfigError, InvalidStateError
from robogym_ray.protocol import robot_server_pb2 as pb
from robogym_ray.robots.registry import CARDS, check_options
from robogym_ray.robots.serve import serve_process
from robogym_ray.robots.server import start_robot_server
from robogym_ray.robots.ur.state import RS_MODE_KEYS
from robogym_ray.serve import serve_defaults
from tests.envs.conftest import success_for

UR10_ROB = "RoboGymRay/EndEffectorPositioningUR10Rob-v0"


def test_the_readmes_ur10_server_serves_the_readmes_ur10_env() -> None:
    # As the issue ran it: `robogym-ray serve --robot ur10`, then the UR10 Rob env resets.
    with serve_process(["--robot", "ur10", "--port", "0"]) as address:
        env = gym.make(UR10_ROB, rs_address=address)
        try:
            obs, _ = env.reset(seed=0)
            _, _, _, _, info = env.step(env.action_space.sample())
        finally:
            env.close()
    assert obs.shape == env.observation_space.shape and "distance" in info


def test_a_server_in_another_mode_is_refused_naming_the_option_it_needs() -> None:
    # A server launched for another task: everything as the env asks but rs_mode.
    robot, scene, options = server_spec_of(UR10_ROB)
    handle = start_robot_server(robot, scene=scene, options={**options, "rs_mode": "only_robot"})
    env = gym.make(UR10_ROB, rs_address=handle.address)
    try:
        with pytest.raises(ConfigError, match="runs rs_mode only_robot") as info:
            env.reset(seed=0)
    finally:
        env.close()
        handle.stop()
    assert "--option rs_mode=1object" in str(info.value) and "rs_mode:=1object" in str(info.value)


def test_a_server_that_cannot_say_its_mode_is_named_by_its_keys(fake_server) -> None:
    # robo-gym's own ROS servers (2.0.x) answer no GetArguments: the key set tells the mode.
    keys = dict.fromkeys(RS_MODE_KEYS["only_robot"], 0.0)
    reply = pb.State(success=True, state_dict=keys, state=list(keys.values()))
    address, _ = fake_server(lambda rpc, req, ctx: success_for(rpc, reply))
    env = EndEffectorPositioningUR(ur_model="ur10", rs_address=address, real_robot=True)
    with pytest.raises(InvalidStateError, match="the server runs rs_mode 'only_robot'") as info:
        env.reset(seed=0)
    env.close()
    assert "--option rs_mode=1object" in str(info.value)


@pytest.mark.parametrize("name", sorted(n for n, card in CARDS.items() if card.serve_env))
def test_every_serve_default_is_valid_for_its_robot(name: str) -> None:
    scene, options = serve_defaults(CARDS[name].serve_env, None, {})
    check_options(name, scene, options)  # every UR model takes the UR10 env's options


def test_options_given_to_serve_replace_the_envs_own() -> None:
    env = CARDS["ur10"].serve_env
    _, options = serve_defaults(env, None, {"rs_mode": "only_robot"})
    assert options["rs_mode"] == "only_robot" and options["action_cycle_rate"] == "10"
    # The launch file reads target_mode when rs_mode is unset: a given one must count.
    _, options = serve_defaults(env, None, {"target_mode": "1moving2points"})
    assert "rs_mode" not in options
    # A given world_name stands for the scene (both would have to agree).
    scene, _ = serve_defaults(env, None, {"world_name": "tabletop_sphere50.world"})
    assert scene is None
    assert serve_defaults(None, "lab_6x8", {"a": "1"}) == ("lab_6x8", {"a": "1"})
