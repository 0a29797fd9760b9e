"""How long a supervised robot server takes to start as a Ray actor, and what its process holds.

A supervisor actor on a local Ray starts ``--servers`` robot servers one after the other (each
``start_server`` returns once the server answers GetState) and stops them; per server: the start
time as the supervisor's caller sees it, the process's resident memory once it answers, and
whether torch is loaded in it. A robot server's process imports the module its actor class is
defined in, so what that module imports every server pays for.

Run it on two trees to compare them (``--tree`` puts a checkout's package first on the path of
this process and of Ray's workers), alternating, on an otherwise idle machine:

    python benchmarks/server_actor_start.py --servers 8 --tree /tmp/before --tree .

Prints one JSON line per tree and round.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import time
from pathlib import Path

ROUND = r"""
import json, os, statistics, sys, time
os.environ.setdefault("RAY_AUTH_MODE", "disabled")
import ray
from robogym_ray.distributed.local_ray import start_local_ray
try:
    from robogym_ray.distributed.robot_actors import start_supervisor
except ImportError:  # a tree from before the robot side had a module of its own
    from robogym_ray.distributed.remote import start_supervisor
from robogym_ray.supervision.server_host import ServerSpec
from robogym_ray.supervision.supervisor import SupervisorConfig

servers, robot = int(sys.argv[1]), sys.argv[2]
start_local_ray(2, log_to_driver=False)
sup = start_supervisor(SupervisorConfig(server_num_cpus=0.01, probe_interval_s=0), name="bench")
starts, rss, torch_in = [], [], []
for _ in range(servers):
    t = time.perf_counter()
    info = ray.get(sup.start_server.remote(ServerSpec(robot)))
    starts.append(time.perf_counter() - t)
    pid = info["pid"]
    status = open(f"/proc/{pid}/status").read()
    rss.append(int(status.split("VmRSS:")[1].split()[0]) / 1024)
    torch_in.append("libtorch" in open(f"/proc/{pid}/maps").read())
ray.get(sup.kill_all.remote())
print(json.dumps({"start_s_median": round(statistics.median(starts), 3),
                  "start_s_all": [round(s, 2) for s in starts],
                  "rss_mib_median": round(statistics.median(rss), 1),
                  "torch_loaded": sum(torch_in)}))
"""


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--servers", type=int, default=8)
    parser.add_argument("--robot", default="mir100")
    parser.add_argument("--rounds", type=int, default=2)
    parser.add_argument("--tree", action="append", default=[], help="a checkout (repeatable)")
    args = parser.parse_args()
    trees = [str(Path(t).resolve()) for t in (args.tree or ["."])]
    print(f"# {time.strftime('%Y-%m-%d')} {platform.machine()} {os.cpu_count()} cores, "
          f"load {os.getloadavg()[0]:.2f}")  # fmt: skip
    for round_ in range(args.rounds):
        for tree in trees:
            env = {**os.environ, "PYTHONPATH": tree, "RAY_AUTH_MODE": "disabled"}
            done = subprocess.run(
                [sys.executable, "-c", ROUND, str(args.servers), args.robot],
                env=env, capture_output=True, text=True, timeout=600, check=True, cwd="/",
            )  # fmt: skip
            result = json.loads(done.stdout.strip().splitlines()[-1])
            print(json.dumps({"tree": tree, "round": round_, "robot": args.robot, **result}))


if __name__ == "__main__":
    main()
