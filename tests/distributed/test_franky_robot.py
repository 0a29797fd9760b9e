"""The FR3 through franky, against franky-sim: a MuJoCo FR3 speaking libfranka's own protocol.

Our robot server with the ``franky`` backend (``serve --robot fr3 --hardware franky``) is driven
through the real-robot contract: the ``EndEffectorPositioningFR3Rob-v0`` env at ``rs_address``,
directly and through the real-robot actor (safety filter, pause, the operator's resume). Nothing
is mocked: libfranka's TCP/UDP protocol runs between franky and the simulator, in real time.
"""

from __future__ import annotations

import time
from collections.abc import Iterator

import gymnasium as gym
import numpy as np
import pytest

from robogym_ray.envs.panda_tasks import normalize
from robogym_ray.envs.registration import server_spec_of
from robogym_ray.errors import RobotServerError
from robogym_ray.robots.hardware import HardwareConfig
from robogym_ray.robots.panda.model import LIMITS, forward_kinematics
from robogym_ray.robots.server import RobotServerHandle, start_robot_server

pytest.importorskip("franky")
pytest.importorskip("franky_sim")
from robogym_ray.robots.panda.franky_sim import FrankySim  # noqa: E402

ROB_ID = "RoboGymRay/EndEffectorPositioningFR3Rob-v0"
STEPS = 50


@pytest.fixture(scope="module")
def sim() -> Iterator[FrankySim]:
    with FrankySim() as simulator:
        yield simulator


@pytest.fixture(scope="module")
def fr3(sim: FrankySim) -> Iterator[RobotServerHandle]:
    """Our server in front of franky-sim's arm, as ``robogym-ray serve`` starts it for the env."""
    robot, _, options = server_spec_of(ROB_ID)
    # The card's cap, so the resets of a CI run take a second or two, not ten.
    handle = start_robot_server(
        robot, options=options, hardware=HardwareConfig("franky", sim.host, 0.3)
    )
    yield handle
    handle.stop()


def test_serve_cli_drives_the_arm_and_sigterm_stops_and_releases_it(sim: FrankySim) -> None:
    """``robogym-ray serve --robot fr3 --hardware franky``: SIGTERM mid-move stops the arm where
    it is and releases it (franky-sim, like the FCI, takes one client at a time). Runs before
    the module's in-process server takes the arm."""
    import franky

    from robogym_ray.protocol import robot_server_pb2 as pb
    from robogym_ray.protocol.client import RobotServerClient
    from robogym_ray.robots.panda.model import READY
    from robogym_ray.robots.panda.state import POSITION_KEYS
    from robogym_ray.robots.serve import serve_process

    args = ["--robot", "fr3", "--hardware", "franky", "--fci-host", sim.host,
            "--dynamics-factor", "0.3", "--option", "rs_mode=only_robot"]  # fmt: skip
    far = READY + np.array([1.2, 0, 0, 0, 0, 0, 0])
    with serve_process(args) as address, RobotServerClient(address) as client:
        client.set_state(pb.State(state_dict=dict(zip(POSITION_KEYS, READY.tolist(), strict=True))))
        client.send_action(far)  # heading 1.2 rad away when the server is stopped
    # serve_process sent SIGTERM and waited for the exit: the arm is ours to connect to now.
    robot = franky.Robot(sim.host, realtime_config=franky.RealtimeConfig.Ignore)
    try:
        state = robot.state
        assert abs(state.q[0] - far[0]) > 0.3, "the arm went on to the target after SIGTERM"
        assert not robot.has_errors
    finally:
        del robot  # release the arm for the fixtures below


def _hold(env: gym.Env, rng: np.random.Generator) -> np.ndarray:
    """An action close to the arm's start pose: what a trained policy sends (small moves)."""
    task = env.unwrapped
    start = normalize(task.start_joints, LIMITS["fr3"])[task.active]
    return np.clip(start + rng.uniform(-0.02, 0.02, start.size), -1, 1).astype(np.float32)


def _franky_state(handle: RobotServerHandle):  # noqa: ANN202 - franky's RobotState
    return handle.core.robot._robot.state  # the backend's own libfranka connection


def test_rob_env_resets_steps_and_reports_what_franky_reports(fr3: RobotServerHandle) -> None:
    env = gym.make(ROB_ID, rs_address=fr3.address)
    rng = np.random.default_rng(0)
    try:
        env.reset(seed=0)
        task = env.unwrapped
        for _ in range(STEPS):
            env.step(_hold(env, rng))
        reply = task.client.get_state()
        sd = reply.state_dict
        q = np.array([sd[f"joint{i}_position"] for i in range(1, 8)])
        ee = np.array([sd[f"ee_to_ref_translation_{a}"] for a in "xyz"])
        # The pose is libfranka's O_T_EE taken back to our frame: it must be our kinematics.
        xyz, _ = forward_kinematics(q)["panda_hand"]
        np.testing.assert_allclose(ee, xyz, atol=1e-4)
        # The joints are franky's, a few ms apart at most while the arm holds its pose.
        np.testing.assert_allclose(q, np.array(_franky_state(fr3).q), atol=5e-3)
        assert fr3.core.calls["set"] >= 1 and fr3.core.calls["action"] >= STEPS
        # A client that goes quiet mid-move (a training stopped): the arm stops short of the
        # move's target instead of finishing it with nobody watching.
        far = q.copy()
        far[0] += 1.2
        task.client.send_action(far)
        time.sleep(1.0)  # the move takes seconds at the task's speed; the stop comes at 80 ms
        assert abs(_franky_state(fr3).q[0] - far[0]) > 0.8
    finally:
        env.close()


def test_a_command_outside_the_fr3_limits_is_refused_and_never_reaches_the_arm(
    fr3: RobotServerHandle,
) -> None:
    from robogym_ray.protocol.client import RobotServerClient

    before = np.array(_franky_state(fr3).q)
    target = before.copy()
    target[5] = 0.25  # exact in float32; inside the Panda's joint 6 range, below the FR3's 0.4398
    with RobotServerClient(fr3.address) as client, pytest.raises(RobotServerError) as refused:
        client.send_action(target)
    assert "action[5] (panda_joint6, abs_pos) = 0.25 is outside [0.439800, 4.621600]" in str(
        refused.value
    )
    np.testing.assert_allclose(np.array(_franky_state(fr3).q), before, atol=5e-3)


@pytest.mark.usefixtures("ray_cluster")
def test_a_dead_arm_pauses_the_actor_and_resume_recovers_it(
    sim: FrankySim, fr3: RobotServerHandle
) -> None:
    from robogym_ray.distributed.real_client import real_robot_actor

    rng = np.random.default_rng(1)
    with real_robot_actor(ROB_ID, fr3.address, token=None) as factory:
        env = gym.make(ROB_ID, rs_address=fr3.address, client_factory=factory)
        try:
            env.reset(seed=1)
            for _ in range(5):
                env.step(_hold(env, rng))
            sim.kill()  # the arm's controller is gone mid-episode
            with pytest.raises(RobotServerError) as stopped:
                for _ in range(200):  # libfranka notices within its UDP timeout (~1 s)
                    env.step(_hold(env, rng))
            assert "fr3 is stopped after an error" in str(stopped.value)
            client = env.unwrapped.client
            assert client.is_paused()
            assert fr3.server is not None and fr3.core.get_arguments().action_cycle_rate > 0

            sim.start()  # the same address, a fresh controller
            import ray

            status = ray.get(client.actor.resume.remote())
            assert status["paused"] is False
            env.reset(seed=2)  # the episode goes on where the operator let it
            for _ in range(5):
                env.step(_hold(env, rng))
            assert fr3.core.robot.fault == "" and fr3.core.robot.faults == 1
        finally:
            env.close()
