"""SendActionGetState calls per second, in-process vs through gRPC on 127.0.0.1.

Each call is one full action cycle: command handler ticks, physics / kinematics, both laser scans
(MiR100) or collision checks (UR10), and the state snapshot. The gRPC server runs in its own
process (``robogym-ray serve``), as it does under the supervisor; the two variants are measured
in alternating rounds within one run so that machine noise hits both alike.

Usage: python benchmarks/robot_server.py [--robots mir100 ur10] [--seconds 3] [--rounds 3]
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import time
from collections.abc import Callable

import grpc
import numpy as np

from robogym_ray.protocol import robot_server_pb2 as pb
from robogym_ray.protocol import robot_server_pb2_grpc as pb_grpc
from robogym_ray.robots.registry import make_robot
from robogym_ray.robots.serve import serve_process
from robogym_ray.robots.server import RobotServerCore

SETUPS = {
    "mir100": {"scene": "lab_6x8", "action": [0.3, 0.2], "options": {}},
    # UR10 as the positioning task serves it: a target sphere (27-key state); actions are
    # small joint moves, ROS order.
    "ur10": {"scene": "tabletop", "action": None, "options": {"rs_mode": "1object"}},
}


def ur_actions(n: int) -> list[list[float]]:
    rng = np.random.default_rng(0)
    base = np.array([1.5, -2.5, 0.0, -1.5, -1.4, 0.0])
    return [list(base + rng.uniform(-0.3, 0.3, 6)) for _ in range(n)]


def rate(
    call: Callable[[list[float]], object], actions: list[list[float]], seconds: float
) -> float:
    n, start = 0, time.perf_counter()
    while time.perf_counter() - start < seconds:
        call(actions[n % len(actions)])
        n += 1
    return n / (time.perf_counter() - start)


def bench(robot: str, seconds: float, rounds: int) -> dict:
    setup = SETUPS[robot]
    actions = [setup["action"]] if setup["action"] else ur_actions(64)
    core = RobotServerCore(
        make_robot(robot, scene=setup["scene"], seed=0, options=setup["options"])
    )
    opts = [f"{k}={v}" for k, v in setup["options"].items()]
    args = ["--robot", robot, "--scene", setup["scene"], *(["--option", *opts] if opts else [])]
    with serve_process(args) as address:
        stub = pb_grpc.RobotServerStub(grpc.insecure_channel(address))
        stub.GetState(pb.Empty(), timeout=10)
        local, remote = [], []
        for _ in range(rounds):
            local.append(rate(core.send_action_get_state, actions, seconds))
            remote.append(
                rate(
                    lambda a: stub.SendActionGetState(pb.Action(action=a), timeout=10),
                    actions,
                    seconds,
                )
            )
    core.close()
    in_proc, via_grpc = float(np.median(local)), float(np.median(remote))
    return {
        "robot": robot,
        "scene": setup["scene"],
        "in_process_per_s": round(in_proc),
        "grpc_per_s": round(via_grpc),
        "grpc_over_in_process": round(via_grpc / in_proc, 3),
        "sim_seconds_per_wall_second_grpc": round(
            via_grpc * core.robot.handler_config.action_cycle, 1
        ),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robots", nargs="+", default=list(SETUPS))
    parser.add_argument("--seconds", type=float, default=3.0)
    parser.add_argument("--rounds", type=int, default=3)
    args = parser.parse_args()
    print(
        f"# {time.strftime('%Y-%m-%d')} {platform.processor() or platform.machine()} "
        f"{os.cpu_count()} cores, python {platform.python_version()}"
    )
    for robot in args.robots:
        print(json.dumps(bench(robot, args.seconds, args.rounds)), flush=True)


if __name__ == "__main__":
    main()
