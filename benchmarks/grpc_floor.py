"""The Python gRPC floor: calls/s of a robot server that does no work at all.

A servicer whose GetState returns a fixed 27-float State, driven by a sync client in another
process over 127.0.0.1 for a few seconds. Any robot server built on Python gRPC on this machine
answers at most this fast, whatever its simulation costs.

Usage: python benchmarks/grpc_floor.py [--seconds 2]
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import time
from concurrent import futures

import grpc

from robogym_ray.protocol import robot_server_pb2 as pb
from robogym_ray.protocol import robot_server_pb2_grpc as pb_grpc


class NoWork(pb_grpc.RobotServerServicer):
    def GetState(self, request: pb.Empty, context: grpc.ServicerContext) -> pb.State:  # noqa: N802
        return pb.State(state=[0.0] * 27, success=True)


def client(address: str, seconds: float) -> None:
    stub = pb_grpc.RobotServerStub(grpc.insecure_channel(address))
    stub.GetState(pb.Empty(), timeout=10)
    n, start = 0, time.perf_counter()
    while time.perf_counter() - start < seconds:
        stub.GetState(pb.Empty(), timeout=10)
        n += 1
    print(round(n / (time.perf_counter() - start)))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=2.0)
    parser.add_argument("--client", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.client:
        client(args.client, args.seconds)
        return
    for workers in (10, 1):
        server = grpc.server(futures.ThreadPoolExecutor(max_workers=workers))
        pb_grpc.add_RobotServerServicer_to_server(NoWork(), server)
        port = server.add_insecure_port("127.0.0.1:0")
        server.start()
        out = subprocess.run(
            [
                sys.executable,
                __file__,
                "--client",
                f"127.0.0.1:{port}",
                "--seconds",
                str(args.seconds),
            ],
            capture_output=True,
            text=True,
            check=True,
        ).stdout.strip()
        print(f"no-op GetState, server with {workers} worker thread(s): {out} calls/s")
        server.stop(0)


if __name__ == "__main__":
    main()
