"""GetArguments, robo-gym-server-modules' newest call (its master after 0.3.0.1, served by
robo-gym-robot-servers 2.1.2's Panda server): a client generated from master's
``robot_server.proto`` asks our robot servers; our client uses it where a server offers it and
falls back where the server answers UNIMPLEMENTED, as robo-gym 2.0.x's servers do.

Master's client runs in a child interpreter: its generated code defines the same protobuf
package as ours, which one process cannot hold twice.
"""

from __future__ import annotations

import json
import sys
import textwrap
from concurrent import futures
from pathlib import Path

import grpc
import gymnasium as gym
import pytest

import robogym_ray  # noqa: F401 - registers the ids
from robogym_ray import children
from robogym_ray.errors import ConfigError
from robogym_ray.protocol import robot_server_pb2_grpc as pb_grpc
from robogym_ray.protocol.client import RobotServerClient
from robogym_ray.realrobot.robot import RealRobot
from robogym_ray.realrobot.safety import safety_for
from robogym_ray.robots.registry import make_robot
from robogym_ray.robots.server import RobotServerCore, RobotServerServicer, start_robot_server

DEPLOY_SIM = "RoboGymRay/IsaacDeployReachUR10eSim-v0"
DEPLOY_ROB = "RoboGymRay/IsaacDeployReachUR10eRob-v0"
EMPTY_SIM, EMPTY_ROB = (
    "RoboGymRay/EmptyEnvironment2UR10Sim-v0",
    "RoboGymRay/EmptyEnvironment2UR10Rob-v0",
)

MASTER_PROTO = """\
syntax = "proto3";
package robot_server;
service RobotServer {
  rpc GetState(Empty) returns (State) {}
  rpc SetState(State) returns (Success) {}
  rpc SendAction(Action) returns (Success) {}
  rpc SendActionGetState(Action) returns (State) {}
  rpc GetArguments(Empty) returns (Arguments) {}
}
message Arguments {
  float action_cycle_rate = 1;
  string rs_mode = 2;
  string action_mode = 3;
  bool success = 4;
}
message Success { bool success = 1; }
message Empty {}
message Action { repeated float action = 1; bool success = 2; }
message State {
  repeated float state = 1;
  map<string, float> float_params = 2;
  map<string, string> string_params = 3;
  map<string, float> state_dict = 4;
  bool success = 5;
}
"""
"""robo-gym-server-modules master's schema (commit 4544746, 2024-10-31), field for field."""

MASTER_CLIENT = """
import json, sys
from grpc_tools import protoc
out = sys.argv[1]
assert protoc.main(["protoc", f"-I{out}", f"--python_out={out}", f"--grpc_python_out={out}",
                    f"{out}/robot_server.proto"]) == 0
sys.path.insert(0, out)
import grpc, robot_server_pb2 as pb, robot_server_pb2_grpc as pb_grpc
answers = []
for address in sys.argv[2:]:
    stub = pb_grpc.RobotServerStub(grpc.insecure_channel(address))
    msg = stub.GetArguments(pb.Empty(), timeout=20)  # what master's Client.get_arguments calls
    answers.append([msg.success, msg.action_cycle_rate, msg.rs_mode, msg.action_mode])
print(json.dumps(answers))
"""

SERVERS = {
    # robot, launch options, expected (rate, rs_mode, action_mode)
    "ur10e": (
        {
            "rs_mode": "only_robot",
            "action_cycle_rate": "60",
            "ee_frame": "wrist_3_link",
            "reference_frame": "base",
            "action_mode": "servo_pos",  # the deploy reach's (ours: streamed targets)
        },
        (60.0, "only_robot", "servo_pos"),
    ),
    "panda": (
        {"rs_mode": "1object", "action_mode": "abs_pos", "action_cycle_rate": "30.0"},
        (30.0, "1object", "abs_pos"),
    ),
    "mir100": ({}, (10.0, "", "")),
}


def test_a_client_of_masters_proto_gets_our_servers_arguments(tmp_path: Path) -> None:
    (tmp_path / "robot_server.proto").write_text(MASTER_PROTO)
    handles = [start_robot_server(r, options=o, seed=0) for r, (o, _) in SERVERS.items()]
    try:
        run = children.run(
            [
                sys.executable,
                "-c",
                textwrap.dedent(MASTER_CLIENT),
                str(tmp_path),
                *(h.address for h in handles),
            ],
            capture_output=True,
            text=True,
            timeout=120,
            check=False,
        )
        assert run.returncode == 0, run.stderr
        answers = json.loads(run.stdout)
        for (robot, (_, want)), handle, answer in zip(
            SERVERS.items(), handles, answers, strict=True
        ):
            assert answer[0] is True, robot
            assert tuple(answer[1:]) == pytest.approx(want) and tuple(answer[2:]) == want[1:]
            # Our own client reads the same answer.
            with RobotServerClient(handle.address) as client:
                ours = client.get_arguments()
            assert ours is not None and ours.action_cycle_rate == pytest.approx(want[0])
    finally:
        for h in handles:
            h.stop()


class ServerWithoutGetArguments(RobotServerServicer):
    """Our servicer with the generated defaults for GetArguments and RecoverFromErrors:
    UNIMPLEMENTED, as a robot server built on robo-gym-server-modules 0.3.0.1 answers."""

    GetArguments = pb_grpc.RobotServerServicer.GetArguments
    RecoverFromErrors = pb_grpc.RobotServerServicer.RecoverFromErrors


def test_our_client_falls_back_and_refuses_a_server_for_another_task() -> None:
    robot, scene, options = gym.make(EMPTY_SIM).unwrapped.server_spec()
    core = RobotServerCore(make_robot(robot, scene=scene, seed=0, options=options))
    server = grpc.server(futures.ThreadPoolExecutor(max_workers=4))
    pb_grpc.add_RobotServerServicer_to_server(ServerWithoutGetArguments(core), server)
    port = server.add_insecure_port("127.0.0.1:0")
    server.start()
    address = f"127.0.0.1:{port}"
    try:
        with RobotServerClient(address) as client:
            assert client.get_arguments() is None  # UNIMPLEMENTED: nothing to check against
            assert client.recover_from_errors() is False  # robo-gym's: nothing to recover
        # An operator's resume of a real robot behind such a server still un-pauses it.
        robot = RealRobot("robo-gym-030", address, safety_for(EMPTY_ROB))
        robot.emergency_stop()
        assert robot.resume()["paused"] is False
        robot.close()
        env = gym.make(EMPTY_ROB, rs_address=address)  # a robo-gym task: taken on trust
        env.reset(seed=0)
        env.step(env.action_space.sample())
        env.close()
        # The deploy reach needs a mode no robo-gym server has: a server that cannot say is
        # refused before anything moves.
        env = gym.make(DEPLOY_ROB, rs_address=address)
        with pytest.raises(ConfigError, match="does not answer GetArguments, so nothing says it "
                           "runs action_mode servo_pos and rs_mode only_robot"):  # fmt: skip
            env.reset(seed=0)
        env.close()
        assert core.calls["set"] == 1  # the first env's reset only
    finally:
        server.stop(0)
        core.close()
    # A server that answers, launched at another rate: refused at the first reset.
    _, scene, options = gym.make(DEPLOY_SIM).unwrapped.server_spec()
    slow = start_robot_server("ur10e", scene=scene, options={**options, "action_cycle_rate": "30"})
    try:
        env = gym.make(DEPLOY_ROB, rs_address=slow.address)
        with pytest.raises(ConfigError, match=r"runs action_cycle_rate 30, this task needs 60"):
            env.reset(seed=0)
        env.close()
        assert slow.core.calls["set"] == 0
    finally:
        slow.stop()
