"""The messages ``fuzz.py`` sends: random, malformed and hostile robot-server and
ServerManager requests, each as (service path, RPC name, serialized bytes)."""

from __future__ import annotations

import math

import numpy as np

from robogym_ray.protocol import robot_server_pb2 as pb
from robogym_ray.protocol import server_manager_pb2 as sm
from robogym_ray.robots.objects import FUNCTIONS
from robogym_ray.robots.registry import check_options
from robogym_ray.robots.ur.state import RS_MODE_KEYS
from robogym_ray.supervision.launch import parse_launch_cmd

# service path prefix -> {rpc: (request type, reply type)}
RS, SM = (
    "/robot_server.RobotServer/",
    "/robo_gym_server_manager.grpc_msgs.server_manager.ServerManager/",
)
_RS = (sm.RobotServer, sm.RobotServer)
RPCS = {RS: {"GetState": (pb.Empty, pb.State), "SetState": (pb.State, pb.Success),
             "SendAction": (pb.Action, pb.Success), "SendActionGetState": (pb.Action, pb.State)},
        SM: {"StartNewServer": _RS, "KillServer": _RS, "KillAllServers": _RS,
             "VerifyConnection": (sm.Empty, sm.Status)}}  # fmt: skip
MAX_TEXT = 5_000_000
"""Longest string sent (``--max-text``)."""
NASTY = (math.nan, math.inf, -math.inf, 1e38, -1e38, 3.4028235e38, 1e-45, -0.0, 1e9, -1e9)
MIR_CMD = "roslaunch mir100_robot_server sim_robot_server.launch world_name:=lab_6x8.world"
UR10_CMD = "roslaunch ur_robot_server ur_robot_server.launch ur_model:=ur10 rs_mode:=1object"
UR_KEYS = RS_MODE_KEYS["1object"]
JOINTS = [k for k in UR_KEYS if k.endswith("_joint_position")]
# Unknown fields (numbers 127 and 128): valid protobuf, as a newer client might send.
UNKNOWN_FIELDS = bytes([0xF8, 0x07, 0x01, 0x82, 0x08, 0x03]) + b"abc"
ROBOTS = {  # robot -> (`robogym-ray serve` arguments, action length, state length)
    "mir100": (["--scene", "lab_6x8"], 2, 1030),
    "ur10": (["--scene", "tabletop", "--option", "rs_mode=1object"], 6, len(UR_KEYS)),
}


# -- message generators (each takes its worker's seeded RNG) --------------------------------
def floats(rng: np.random.Generator, n: int) -> list[float]:
    values = rng.normal(0.0, rng.choice([1.0, 10.0, 1e6]), n)
    nasty = rng.random(n) < rng.choice([0.0, 0.05, 0.5])
    values[nasty] = rng.choice(NASTY, int(nasty.sum()))
    return values.tolist()


def text(rng: np.random.Generator) -> str:
    # Mostly short; now and then beyond the 2,000-character clip and gRPC's 4 MB message limit.
    n = int(rng.choice([0, 1, 8, 64, 1_000, 100_000, 1_000_000, 5_000_000],
                       p=[0.1, 0.2, 0.3, 0.2, 0.15, 0.03, 0.015, 0.005]))  # fmt: skip
    n = min(n, MAX_TEXT)
    if n > 1_000:
        return chr(int(rng.integers(32, 0xD7FF))) * n
    codes = rng.integers(0, 128 if rng.random() < 0.5 else 0x110000, n)
    return "".join(map(chr, codes[(codes < 0xD800) | (codes > 0xDFFF)]))  # UTF-8 only


def near_state(rng: np.random.Generator, robot: str) -> pb.State:
    """A plausible SetState with at most one thing wrong: gets past the first checks."""
    if robot == "mir100":
        state = np.zeros(rng.choice([6, 1030]))
        state[:6] = rng.uniform(-4, 4, 6)
        state[1021:] = rng.uniform(-4, 4, len(state[1021:]))  # obstacle poses
        if rng.random() < 0.7:
            state[rng.choice([rng.integers(6), rng.integers(len(state))])] = rng.choice(NASTY)
        return pb.State(state=state.tolist())
    values = dict.fromkeys(UR_KEYS, 0.0) | dict(zip(JOINTS, rng.uniform(-3, 3, 6), strict=True))
    function = str(rng.choice([*FUNCTIONS, "", "fixed"]))
    msg = pb.State(state_dict=values, string_params={"object_0_function": function})
    for name in ("x", "y", "z", "z_amplitude", "n_points", "n_sampling_points", "hold_a"):
        msg.float_params[f"object_0_{name}"] = rng.uniform(-1, 1) * rng.choice([1, 1e3])
    match rng.integers(5):  # 4: nothing wrong but the ranges
        case 0:
            msg.state_dict[str(rng.choice(JOINTS))] = rng.choice(NASTY)
        case 1:
            msg.state_dict[text(rng)] = 0.0
        case 2:
            del msg.state_dict[str(rng.choice(JOINTS))]
        case 3:
            msg.float_params[str(rng.choice(list(msg.float_params)))] = rng.choice(NASTY)
    return msg


def robot_message(rng: np.random.Generator, robot: str) -> tuple[str, str, bytes]:
    """(kind, rpc, serialized request) of one random robot-server call."""
    kinds = ["get", "set_random", "set_near", "action_random", "action_near", "unknown_fields",
             "bad_method"]  # fmt: skip
    kind = rng.choice(kinds, p=[0.1, 0.2, 0.2, 0.2, 0.2, 0.05, 0.05])
    if kind == "get":
        return kind, "GetState", b""
    if kind == "set_random":
        msg = pb.State(state=floats(rng, int(rng.integers(0, 2100))), success=rng.random() < 0.5)
        for _ in range(rng.integers(0, 4)):
            msg.state_dict[text(rng)] = floats(rng, 1)[0]
            msg.float_params[text(rng)] = floats(rng, 1)[0]
            msg.string_params[text(rng)] = text(rng)
        return kind, "SetState", msg.SerializeToString()
    if kind == "set_near":
        return kind, "SetState", near_state(rng, robot).SerializeToString()
    n = ROBOTS[robot][1]
    action = rng.uniform(-1, 1, n) if kind != "action_random" else floats(rng, rng.integers(20))
    if kind == "action_near" and rng.random() < 0.5:
        action[rng.integers(n)] = rng.choice(NASTY)
    payload = pb.Action(action=list(action)).SerializeToString()
    if kind == "bad_method":
        return kind, str(rng.choice(["NoSuchRpc", "getstate", text(rng)[:64]])), payload
    rpc = str(rng.choice(["SendAction", "SendActionGetState"]))
    return kind, rpc, payload + (UNKNOWN_FIELDS if kind == "unknown_fields" else b"")


def would_start(cmd: str) -> bool:
    try:
        launch = parse_launch_cmd(cmd)
        check_options(launch.robot, None, launch.options)
    except Exception:  # noqa: BLE001 - any refusal will do
        return False
    return True


def manager_message(rng: np.random.Generator) -> tuple[str, str, bytes]:
    kind = rng.choice(["start_garbage", "start_near", "kill", "kill_all", "verify",
                       "unknown_fields"], p=[0.25, 0.45, 0.15, 0.02, 0.08, 0.05])  # fmt: skip
    port = int(rng.choice([rng.integers(-(2**31), 2**31), rng.integers(0, 65536)]))
    if kind == "verify":
        return kind, "VerifyConnection", b""
    if kind in ("kill", "kill_all", "unknown_fields"):
        raw = sm.RobotServer(port=port, cmd=text(rng)[:100]).SerializeToString()
        rpc = "KillServer" if kind != "kill_all" else "KillAllServers"
        return kind, rpc, raw + (UNKNOWN_FIELDS if kind == "unknown_fields" else b"")
    cmd = text(rng)
    if kind == "start_near":  # roslaunch-shaped: bad files, models, options, values, tokens
        names = ["world_name", "robot_x", "robot_y", "robot_yaw", "ur_model", "rs_mode", "x",
                 "action_cycle_rate", "n_objects", "gui", "ee_frame"]  # fmt: skip
        values = ["nan", "inf", "-inf", "1e9", "0", "-1", "", "ur99", "lab_6x8.world", "true",
                  "1object", "ur10", "0.5"]  # fmt: skip
        package = rng.choice(["mir100_robot_server", "ur_robot_server", cmd])
        launch = rng.choice(["sim_robot_server.launch", "ur_robot_server.launch", cmd])
        tokens = ["roslaunch", str(package), str(launch)]
        tokens += [f"{rng.choice(names)}:={rng.choice(values)}" for _ in range(rng.integers(5))]
        if rng.random() < 0.3:
            tokens.insert(int(rng.integers(3, len(tokens) + 1)), text(rng))
        cmd = str(rng.choice([" ", "         ", "\t"])).join(tokens)
    if would_start(cmd):  # only the few deliberate starts may load PyBullet in the manager
        cmd += " not_an_argument"
    msg = sm.RobotServer(cmd=cmd, gui=rng.random() < 0.5, port=port)
    return kind, "StartNewServer", msg.SerializeToString()


def undecodable(rng: np.random.Generator, request_type: type) -> bytes:
    """Bytes that ``request_type`` cannot parse: corrupt wire format, bad UTF-8, truncation."""
    while True:
        raw = [rng.bytes(int(rng.integers(1, 64))), b"\xff" * 11, b"\x1a\x03\x0a\x01\xff",
               b"\x0a\x10\x00"][int(rng.integers(4))]  # fmt: skip
        try:
            request_type.FromString(raw)
        except Exception:  # noqa: BLE001 - a DecodeError is what we are after
            return raw


# -- calling and checking -------------------------------------------------------------------
