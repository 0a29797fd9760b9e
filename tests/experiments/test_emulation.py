"""The emulated real robot: latency, bias, noise (seeded), dynamics, and the protocol intact."""

from __future__ import annotations

import numpy as np
import pytest

from robogym_ray.errors import ConfigError
from robogym_ray.protocol import robot_server_pb2 as pb
from robogym_ray.protocol import robot_server_pb2_grpc as pb_grpc
from robogym_ray.robots.base import StateRequest
from robogym_ray.robots.emulation import EmulatedRobot, EmulationConfig, emulate
from robogym_ray.robots.registry import make_robot
from robogym_ray.robots.server import RobotServerCore, start_robot_server

QUIET = EmulationConfig(
    laser_noise_sigma=0.0,
    joint_noise_sigma=0.0,
    latency_ticks=0,
    velocity_scale=1.0,
    acceleration_scale=1.0,
    actuation_bias=0.0,
)


def mir_core(cfg: EmulationConfig, seed: int = 0) -> RobotServerCore:
    return RobotServerCore(emulate(make_robot("mir100", scene="empty", seed=seed), cfg, seed))


def velocities(core: RobotServerCore, actions: int) -> list[float]:
    out = []
    for _ in range(actions):
        core.send_action([0.5, 0.0])
        out.append(float(core.get_state().state[6]))
    return out


@pytest.mark.parametrize("k", [0, 1, 3])
def test_a_command_takes_effect_k_ticks_later(k: int) -> None:
    # MiR100: one actuation tick per 0.1 s action, so k ticks = k actions.
    core = mir_core(EmulationConfig(**{**QUIET.__dict__, "latency_ticks": k}))
    try:
        v = velocities(core, k + 2)
        assert v[:k] == [0.0] * k and v[k] > 0.0
        plain = velocities(mir_core(QUIET), 2)
        assert v[k:] == pytest.approx(plain)
        # SetState empties the delay line: the robot is at rest and stays so for k ticks.
        state = np.zeros(1030)
        state[0:3], state[3:6] = (1.0, 1.0, 0.0), (0.0, 0.0, 0.0)
        core.set_state(StateRequest(state=state))
        assert velocities(core, 1)[0] == (0.0 if k else pytest.approx(plain[0]))
    finally:
        core.close()


def test_bias_and_dynamics_scale_change_the_motion() -> None:
    biased = mir_core(EmulationConfig(**{**QUIET.__dict__, "actuation_bias": 0.05}))
    slow = mir_core(EmulationConfig(**{**QUIET.__dict__, "acceleration_scale": 0.5}))
    plain = mir_core(QUIET)
    try:
        v_plain, v_bias, v_slow = (velocities(c, 5) for c in (plain, biased, slow))
        assert v_bias[-1] == pytest.approx(0.55) and v_plain[-1] == pytest.approx(0.5)
        assert v_slow[0] == pytest.approx(v_plain[0] / 2)  # acceleration-limited first cycle
        assert biased.get_state().state[7] == pytest.approx(0.05)  # omega bias: a slow turn
    finally:
        for c in (plain, biased, slow):
            c.close()


def scan_after_one_action(core: RobotServerCore) -> np.ndarray:
    core.send_action([0.5, 0.0])
    return np.asarray(core.get_state().state[8:1020])


def test_laser_noise_is_seeded_and_clipped_to_the_scanner_range() -> None:
    cfg = EmulationConfig(**{**QUIET.__dict__, "laser_noise_sigma": 0.05})
    cores = [mir_core(cfg, seed=1), mir_core(cfg, seed=1), mir_core(cfg, seed=2), mir_core(QUIET)]
    try:
        same_a, same_b, other, truth = (scan_after_one_action(c) for c in cores)
        np.testing.assert_array_equal(same_a, same_b)
        assert not np.array_equal(same_a, other)
        assert 0.02 < np.std(same_a - truth) < 0.08
        assert same_a.min() >= 0.05 and same_a.max() <= 29.0
    finally:
        for c in cores:
            c.close()


def test_ur_joint_noise_latency_and_bias_keep_one_target_per_action() -> None:
    cfg = EmulationConfig(
        joint_noise_sigma=0.01,
        latency_ticks=2,
        actuation_bias=0.01,
        velocity_scale=0.5,
        noise_seed=7,
    )
    robot = emulate(make_robot("ur10", options={"rs_mode": "1object"}, seed=0), cfg)
    assert isinstance(robot, EmulatedRobot)
    assert robot.inner.config.max_velocity_scale_factor == pytest.approx(0.5)
    core = RobotServerCore(robot)
    try:
        truth = robot.inner.joint_positions
        noisy = core.get_state().state_dict["base_joint_position"]
        assert noisy != truth[0] and abs(noisy - truth[0]) < 0.05
        core.send_action([0.0] * 6)
        # The arm heads for target + bias (one target per action, as without emulation).
        assert robot.inner._target == pytest.approx(np.full(6, 0.01))  # noqa: SLF001
    finally:
        core.close()


def test_grpc_protocol_is_intact() -> None:
    handle = start_robot_server("mir100", scene="lab_6x8", seed=0, emulation=EmulationConfig())
    stub = pb_grpc.RobotServerStub(__import__("grpc").insecure_channel(handle.address))
    try:
        assert len(stub.GetState(pb.Empty(), timeout=5).state) == 1030
        state = np.zeros(1030, dtype=np.float32)
        state[0:3], state[3:6] = (2.0, 0.0, 0.0), (-1.0, -2.5, 0.3)
        assert stub.SetState(pb.State(state=state.tolist()), timeout=5).success
        msg = stub.SendActionGetState(pb.Action(action=[0.3, 0.1]), timeout=5)
        assert msg.success and len(msg.state) == 1030 and list(msg.state[0:3]) == [2.0, 0.0, 0.0]
        bad = stub.SendAction(pb.Action(action=[0.1]), timeout=5)
        assert not bad.success  # wrong length refused the usual way
        assert not stub.SetState(pb.State(state=[1.0, 2.0]), timeout=5).success
    finally:
        handle.stop()


def test_rob_env_leaves_the_cubes_where_they_stand() -> None:
    """robo-gym's Real MiR env sends zero cube poses; a real server ignores them, so must ours.

    Teleported to the zeros, the cubes would stand on the robot at the origin and pin it there
    (every Rob episode a timeout). The Sim env's resets still place the cubes (--variant sim).
    """
    import gymnasium as gym

    import robogym_ray  # noqa: F401 - registers the ids

    handle = start_robot_server("mir100", scene="lab_6x8", seed=0, emulation=QUIET)
    robot = handle.core.robot.inner
    before = robot.obstacle_poses()
    rob = gym.make("RoboGymRay/ObstacleAvoidanceMir100Rob-v0", rs_address=handle.address)
    sim = gym.make("RoboGymRay/ObstacleAvoidanceMir100Sim-v0", rs_address=handle.address)
    try:
        rob.reset(seed=0)
        np.testing.assert_allclose(robot.obstacle_poses(), before, atol=1e-6)
        assert np.all(np.hypot(*before[:, :2].T) > 1.0)  # clear of the robot at the origin
        for _ in range(20):
            _, _, terminated, truncated, info = rob.step(np.array([1.0, 0.0], np.float32))
            assert not (terminated or truncated), info
        assert np.hypot(*rob.unwrapped.client.get_state().state[3:5]) > 0.3  # it drove off
        sim.reset(seed=5)
        placed = sim.unwrapped.obstacles
        np.testing.assert_allclose(robot.obstacle_poses()[:, :2], placed[:, :2], atol=1e-6)
    finally:
        rob.close()
        sim.close()
        handle.stop()


def test_config_is_checked() -> None:
    with pytest.raises(ConfigError, match="latency_ticks"):
        EmulationConfig(latency_ticks=-1)
    with pytest.raises(ConfigError, match="velocity_scale"):
        EmulationConfig(velocity_scale=0.0)
