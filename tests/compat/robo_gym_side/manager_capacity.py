"""Runs in the robo-gym venv: ask a server manager for many robot servers, never killing one.

    python manager_capacity.py HOST PORT COUNT CLIENTS --out FILE

COUNT servers through robo-gym-server-modules' own server-manager ``Client.start_new_server``
(with its retries), from CLIENTS threads at once (environments being built side by side), while
another thread calls VerifyConnection every 0.5 s (robo-gym's discovery call). Every gRPC call
is timed through a wrapper around the client's stub; the JSON holds the timings and outcomes.
"""

from __future__ import annotations

import argparse
import json
import threading
import time
from concurrent.futures import ThreadPoolExecutor

from robo_gym_server_modules.server_manager.client import Client
from robo_gym_server_modules.server_manager.grpc_msgs.python3 import server_manager_pb2

CMD = "roslaunch mir100_robot_server sim_robot_server.launch world_name:=lab_6x8.world"


class TimedStub:
    """The client's stub, timing each StartNewServer call (success or not)."""

    def __init__(self, stub, calls: list) -> None:
        self._stub = stub
        self._calls = calls

    def StartNewServer(self, request, timeout=None):  # noqa: N802 - the stub's name
        began = time.monotonic()
        try:
            reply = self._stub.StartNewServer(request, timeout=timeout)
        except Exception as exc:  # noqa: BLE001 - robo-gym's client swallows these; we record
            self._calls.append({"s": time.monotonic() - began, "ok": False, "info": repr(exc)})
            raise
        self._calls.append(
            {"s": time.monotonic() - began, "ok": reply.success, "info": reply.info[:200]}
        )
        return reply


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("host")
    parser.add_argument("port", type=int)
    parser.add_argument("count", type=int)
    parser.add_argument("clients", type=int)
    parser.add_argument("--out", required=True)
    args = parser.parse_args()

    calls: list = []
    verify: list = []
    done = threading.Event()
    probe = Client(args.host, args.port, args.port + 1)

    def verify_loop() -> None:
        while not done.is_set():
            began = time.monotonic()
            try:
                ok = probe.stub.VerifyConnection(server_manager_pb2.Empty(), timeout=20).alive
            except Exception:  # noqa: BLE001 - recorded as a failed call
                ok = False
            verify.append({"s": time.monotonic() - began, "ok": ok})
            done.wait(0.5)

    def one_env(_: int) -> dict:
        client = Client(args.host, args.port, args.port + 1)  # one per env, as robo-gym does
        client.stub = TimedStub(client.stub, calls)
        began = time.monotonic()
        try:
            address = client.start_new_server(cmd=CMD, gui=False)
        except RuntimeError as exc:  # robo-gym's "Failed 10 tentatives ..."
            return {"address": None, "error": str(exc), "s": time.monotonic() - began}
        return {"address": address, "error": None, "s": time.monotonic() - began}

    verifier = threading.Thread(target=verify_loop, daemon=True)
    verifier.start()
    began = time.monotonic()
    with ThreadPoolExecutor(max_workers=args.clients) as pool:
        envs = list(pool.map(one_env, range(args.count)))
    total = time.monotonic() - began
    done.set()
    verifier.join(timeout=30)
    with open(args.out, "w") as out:
        json.dump({"envs": envs, "calls": calls, "verify": verify, "total_s": total}, out)


if __name__ == "__main__":
    main()
