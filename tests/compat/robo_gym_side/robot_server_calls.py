"""Runs in the robo-gym venv: drive one robot server with robo-gym-server-modules' own Client.

    python robot_server_calls.py ADDRESS {mir100|ur} --out FILE

Makes the calls robo-gym's envs make (spec a.2, c.1, c.2.3) and writes what the client returned
as JSON; the assertions live in the pytest module, which cannot import this protobuf 3.20 stack.
"""

from __future__ import annotations

import argparse
import json

from robo_gym_server_modules.robot_server.client import Client
from robo_gym_server_modules.robot_server.grpc_msgs.python import robot_server_pb2

# MiR100: lab_6x8 interior; obstacles parked away from the robot's short drive along +x.
MIR_TARGET = [1.0, 2.5, 0.0]
MIR_POSE = [-1.0, -2.5, 0.0]
MIR_OBSTACLES = [-2.0, 0.0, 0.0, 0.0, 0.0, 0.0, 2.0, 0.0, 0.0]
# UR: EndEffectorPositioning's reset pose (env order) and an object point (m, base_link).
UR_GOAL = {
    "base": 0.0,
    "shoulder": -2.5,
    "elbow": 1.5,
    "wrist_1": -1.5,
    "wrist_2": -1.4,
    "wrist_3": 0.0,
}
UR_OBJECT = {"object_0_x": 0.5, "object_0_y": 0.3, "object_0_z": 0.4}
UR_PAN_STEP = 0.2  # rad added to shoulder_pan by the action


def state_msg_json(msg: robot_server_pb2.State) -> dict:
    return {
        "state": list(msg.state),
        "state_dict": dict(msg.state_dict),
        "float_params": dict(msg.float_params),
        "string_params": dict(msg.string_params),
        "success": bool(msg.success),
    }


def mir100(client: Client) -> dict:
    out: dict = {"initial": list(client.get_state())}
    # What NoObstacle/ObstacleAvoidance send on reset: a 1030 vector, zeros except these.
    request = [0.0] * 1030
    request[0:3], request[3:6] = MIR_TARGET, MIR_POSE
    request[1021:1030] = MIR_OBSTACLES
    out["request"] = request
    out["set_state"] = client.set_state(request)
    out["after_set"] = list(client.get_state())
    out["get_state_msg"] = state_msg_json(client.get_state_msg())
    actions = []
    for _ in range(3):  # the env's step: SendAction([0.5 a0, 0.7 a1]) then GetState
        actions.append(client.send_action([0.5, 0.0]))
    out["send_action"] = actions
    out["after_actions"] = list(client.get_state())
    out["send_action_get_state"] = state_msg_json(client.send_action_get_state([0.0, 0.7]))
    return out


def ur(client: Client) -> dict:
    first = client.get_state_msg()
    out: dict = {"initial": state_msg_json(first)}
    # What the UR envs send on reset (c.2.3): every key of the composition with 0.0 except the
    # joint goals, state empty, object 0 described by string/float params.
    state_dict = {key: 0.0 for key in first.state_dict}
    state_dict.update({f"{name}_joint_position": q for name, q in UR_GOAL.items()})
    request = robot_server_pb2.State(
        state_dict=state_dict,
        string_params={"object_0_function": "fixed_position"},
        float_params=UR_OBJECT,
    )
    out["set_state"] = client.set_state_msg(request)
    out["after_set"] = state_msg_json(client.get_state_msg())
    # Absolute targets in ROS order [elbow, shoulder_lift, shoulder_pan, wrist_1, wrist_2, wrist_3].
    g = UR_GOAL
    action = [
        g["elbow"],
        g["shoulder"],
        g["base"] + UR_PAN_STEP,
        g["wrist_1"],
        g["wrist_2"],
        g["wrist_3"],
    ]
    out["action"] = action
    out["send_action"] = client.send_action(action)
    out["after_action"] = state_msg_json(client.get_state_msg())
    out["send_action_get_state"] = state_msg_json(client.send_action_get_state(action))
    return out


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("address")
    parser.add_argument("robot", choices=["mir100", "ur"])
    parser.add_argument("--out", required=True)
    args = parser.parse_args()
    client = Client(args.address)
    result = mir100(client) if args.robot == "mir100" else ur(client)
    with open(args.out, "w") as f:
        json.dump(result, f)


if __name__ == "__main__":
    main()
