"""Starting a child process beside live gRPC calls: how many die before their program runs, and
what a start costs, for ``robogym_ray.children`` against the ``preexec_fn`` it replaced.

The process runs a gRPC server on 127.0.0.1 and, with ``--calls``, a thread that keeps calling
it, as a supervisor or a test process does; then it starts ``--children`` children running
``true``, one after the other, each way in turn for ``--rounds`` rounds. A child that a fork
left with grpcio's poller thread aborts before ``exec`` (grpc/grpc#43055) with
``epoll_wait error: Bad file descriptor``. Prints one JSON line per way and round:

    python benchmarks/child_start.py --children 300 --rounds 2 --calls
"""

from __future__ import annotations

import argparse
import ctypes
import json
import os
import platform
import signal
import subprocess
import threading
import time
from collections.abc import Callable, Iterator
from concurrent import futures
from contextlib import contextmanager

import grpc

from robogym_ray import children

_PRCTL = ctypes.CDLL(None, use_errno=True).prctl


def preexec_run(args: list[str], **kwargs) -> subprocess.CompletedProcess:
    """The start ``children`` used until 2026-11-29: the signal set in a ``preexec_fn``."""
    parent = os.getpid()

    def arm() -> None:
        _PRCTL(children.PR_SET_PDEATHSIG, int(signal.SIGTERM), 0, 0, 0)
        if os.getppid() != parent:
            os.kill(os.getpid(), signal.SIGTERM)

    return subprocess.run(args, preexec_fn=arm, **kwargs)


WAYS: dict[str, Callable[..., subprocess.CompletedProcess]] = {
    "preexec_fn": preexec_run,
    "children.run": children.run,
}


@contextmanager
def live_grpc_calls(calling: bool = True) -> Iterator[list[bool]]:
    """A gRPC echo server on 127.0.0.1 in this process, called once; with ``calling``, a thread
    that keeps calling it until the block ends. Yields the calls' outcomes (True: echoed)."""
    echo = grpc.unary_unary_rpc_method_handler(lambda request, context: request)
    server = grpc.server(futures.ThreadPoolExecutor(max_workers=4))
    server.add_generic_rpc_handlers([grpc.method_handlers_generic_handler("b.Echo", {"Do": echo})])
    port = server.add_insecure_port("127.0.0.1:0")
    server.start()
    channel = grpc.insecure_channel(f"127.0.0.1:{port}")
    call = channel.unary_unary("/b.Echo/Do")
    answered = [call(b"x", timeout=30) == b"x"]
    stop = threading.Event()

    def keep_calling() -> None:
        while not stop.is_set():
            answered.append(call(b"x", timeout=30) == b"x")

    caller = threading.Thread(target=keep_calling)
    if calling:
        caller.start()
    try:
        yield answered
    finally:
        stop.set()
        if calling:
            caller.join()
        channel.close()
        server.stop(grace=None)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--children", type=int, default=300)
    parser.add_argument("--rounds", type=int, default=2)
    parser.add_argument("--calls", action="store_true", help="keep a thread calling the server")
    args = parser.parse_args()

    with live_grpc_calls(calling=args.calls):
        for round_ in range(args.rounds):
            for way, run in WAYS.items():
                began, died = time.perf_counter(), 0
                for _ in range(args.children):
                    done = run(["true"], capture_output=True, timeout=60)
                    died += done.returncode != 0
                took = time.perf_counter() - began
                print(json.dumps({
                    "way": way, "round": round_, "children": args.children, "died": died,
                    "ms_per_child": round(1000 * took / args.children, 2),
                    "calls": args.calls, "grpcio": grpc.__version__,
                    "machine": platform.node(), "load": os.getloadavg()[0],
                }), flush=True)  # fmt: skip


if __name__ == "__main__":
    main()
