"""Fuzz the robot servers and the server manager with random and malformed gRPC messages.

The bar it checks (set 2026-11-23): >= 10,000 messages at a MiR100 and at a UR10 robot server
and >= 2,000 at the server manager, from 8 threads, on 127.0.0.1, with 0 crashes (the server still
answers a valid call after every batch and at the end), 0 hangs (every call returns before its
deadline; DEADLINE_EXCEEDED calls are listed), 0 corrupted states (after fuzzing, a valid
SetState + GetState gives back what was set, finite and of the right length, identical to the
same round trip before fuzzing) and the server's RSS flat from the end of the first (warm-up)
batch to the end.

Each server runs in its own child process (a PID to measure): ``robogym-ray serve`` for the
robots; this script with ``--child manager`` (a ServerManager over an in-process supervisor,
no Ray) and ``--child bare`` (the generated RobotServer base servicer: every RPC UNIMPLEMENTED).
Undecodable bytes leak memory inside gRPC; they are kept out of the main run and measured on
their own, at the robot server and at the bare server, to show the leak is gRPC's.

Prints a markdown report for docs/benchmarks.md (RSS after every batch too: multi-MB strings
move the heap's high-water mark by ~10 MB, so judge flatness by the plateau, or rerun with
``--max-text 1000``); exits 1 on any crash, hang or corrupted state, 2 if --seconds ran out
before the message counts were reached.

Usage: python benchmarks/fuzz.py [--messages 10000] [--manager-messages 2000] [--threads 8]
           [--batches 10] [--leak-messages 10000] [--max-text 5000000] [--seconds 1200]
           [--deadline 10] [--seed 0]
"""

from __future__ import annotations

import argparse
import contextlib
import math
import os
import platform
import shlex
import signal
import subprocess
import sys
import tempfile
import time
import zlib
from collections import Counter
from collections.abc import Callable, Iterator
from concurrent import futures
from dataclasses import dataclass, field
from functools import partial

import grpc
import numpy as np
from fuzz_messages import (  # noqa: E402 - beside this script
    JOINTS,
    MAX_TEXT,
    MIR_CMD,
    ROBOTS,
    RPCS,
    RS,
    SM,
    UR10_CMD,
    UR_KEYS,
    manager_message,
    robot_message,
    undecodable,
)

from robogym_ray.protocol import robot_server_pb2 as pb
from robogym_ray.protocol import robot_server_pb2_grpc as pb_grpc
from robogym_ray.protocol import server_manager_pb2 as sm
from robogym_ray.protocol import server_manager_pb2_grpc as sm_grpc


@dataclass
class Target:
    name: str
    address: str
    proc: subprocess.Popen
    log: str
    prefix: str = RS
    state_len: int = 0
    """A valid GetState's state length (robot servers)."""
    outcomes: Counter = field(default_factory=Counter)
    hangs: list[str] = field(default_factory=list)
    problems: list[str] = field(default_factory=list)
    rss: list[float] = field(default_factory=list)
    sent: int = 0
    seconds: float = 0.0

    def __post_init__(self) -> None:
        self.channel = grpc.insecure_channel(self.address)

    def call(self, rpc: str, payload: bytes, deadline: float) -> str:
        """ok, refused (with a reason), refused_silently, or the gRPC status code."""
        reply_type = RPCS[self.prefix].get(rpc, (None, None))[1]
        parse = reply_type and reply_type.FromString
        stub = self.channel.unary_unary(self.prefix + rpc, response_deserializer=parse)
        try:
            reply, call = stub.with_call(payload, timeout=deadline)
        except grpc.RpcError as exc:
            return exc.code().name
        if getattr(reply, "success", getattr(reply, "alive", True)):
            return "ok"
        why = dict(call.trailing_metadata() or ()).get("robogym-error", getattr(reply, "info", ""))
        return "refused" if why else "refused_silently"

    def rss_mb(self) -> float:
        with open(f"/proc/{self.proc.pid}/status") as status:
            return int(next(x for x in status if x.startswith("VmRSS:")).split()[1]) / 1024

    def check(self) -> str | None:
        """None if the process runs and answers validly (robots: a full, finite state)."""
        if self.proc.poll() is not None:
            with open(self.log) as log:
                return f"process exited with {self.proc.returncode}: {log.read()[-600:]}"
        try:
            if self.prefix == SM:
                manager = sm_grpc.ServerManagerStub(self.channel)
                alive = manager.VerifyConnection(sm.Empty(), timeout=10).alive
                return None if alive else "VerifyConnection: alive=false"
            state = pb_grpc.RobotServerStub(self.channel).GetState(pb.Empty(), timeout=10).state
        except grpc.RpcError as exc:
            return f"{exc.code().name}: {exc.details()}"
        finite = bool(np.all(np.isfinite(state)))
        ok = len(state) == self.state_len and finite
        return None if ok else f"GetState: {len(state)} values, finite {finite}"


def fuzz(target: Target, make: Callable, total: int, args: argparse.Namespace, t_end: float,
         pool: futures.ThreadPoolExecutor) -> None:  # fmt: skip
    """Send ``total`` messages in batches from ``args.threads`` threads; check after each."""

    def worker(seed: list[int], count: int) -> Counter:
        rng, seen = np.random.default_rng(seed), Counter()
        for _ in range(count):
            if time.monotonic() > t_end:
                break
            kind, rpc, payload = make(rng)
            seen[outcome := target.call(rpc, payload, args.deadline)] += 1
            if outcome == "DEADLINE_EXCEEDED":
                target.hangs.append(f"{kind} {rpc} ({len(payload)} bytes)")
        return seen

    start, batch = time.monotonic(), 0
    while target.sent < total and time.monotonic() < t_end and not target.problems:
        n = min(math.ceil(total / args.batches), total - target.sent)
        stream = [args.seed, zlib.crc32(target.name.encode()), batch]  # hash() is salted
        jobs = [pool.submit(worker, [*stream, w], n // args.threads + (w < n % args.threads))
                for w in range(args.threads)]  # fmt: skip
        for job in jobs:
            target.outcomes.update(seen := job.result())
            target.sent += seen.total()
        batch += 1
        if (problem := target.check()) is not None:
            target.problems.append(f"after {target.sent} messages: {problem}")
        else:
            target.rss.append(target.rss_mb())
    target.seconds = time.monotonic() - start


def round_trip(target: Target, robot: str) -> tuple[pb.State, float]:
    """A valid SetState + GetState: (the reply, max |got - set| over the values set, all of
    them exact in float32)."""
    if robot == "mir100":
        state = np.zeros(1030)
        state[:6] = [2.0, 0.0, 0.25, -1.0, -2.5, 0.5]  # target, robot pose
        state[1021:] = [-2.0, 0.0, 0.0, 0.0, 0.5, 0.0, 2.0, -0.5, 0.0]
        msg, expect = pb.State(state=state.tolist()), {f"state[{i}]": state[i] for i in range(8)}
    else:
        joints = dict(zip(JOINTS, [0.0, -2.5, 1.5, -1.5, -1.375, 0.0], strict=True))
        obj = {"object_0_x": 0.5, "object_0_y": 0.25, "object_0_z": 0.625}
        msg = pb.State(state_dict=dict.fromkeys(UR_KEYS, 0.0) | joints, float_params=obj,
                       string_params={"object_0_function": "fixed_position"})  # fmt: skip
        expect = {k: v for k, v in msg.state_dict.items() if "joint" in k}
        expect |= {f"object_0_to_ref_translation_{a}": obj[f"object_0_{a}"] for a in "xyz"}
    stub = pb_grpc.RobotServerStub(target.channel)
    try:
        if not stub.SetState(msg, timeout=10).success:
            return pb.State(), math.inf
        got = stub.GetState(pb.Empty(), timeout=10)
    except grpc.RpcError:
        return pb.State(), math.inf
    values = {f"state[{i}]": v for i, v in enumerate(got.state)} | dict(got.state_dict)
    return got, max(abs(values.get(k, math.inf) - v) for k, v in expect.items())


def leak(target: Target, name: str, args: argparse.Namespace, pool: futures.ThreadPoolExecutor,
         decodable: bool = False) -> tuple[str, Counter, float]:  # fmt: skip
    """Send undecodable (or, as a control, valid empty) requests: (name, replies, RSS growth)."""

    def worker(w: int, count: int) -> Counter:
        rng, seen, rpcs = np.random.default_rng([args.seed, 99, w]), Counter(), list(RPCS[RS])
        for _ in range(count):
            rpc = "GetState" if decodable else rpcs[int(rng.integers(4))]
            payload = b"" if decodable else undecodable(rng, RPCS[RS][rpc][0])
            seen[target.call(rpc, payload, args.deadline)] += 1
        return seen

    grown = 0.0
    for count in (min(1000, args.leak_messages), args.leak_messages):  # warm-up, measured
        before = target.rss_mb()
        jobs = [pool.submit(worker, w, count // args.threads) for w in range(args.threads)]
        seen = sum((job.result() for job in jobs), Counter())
        grown = target.rss_mb() - before
    if (problem := target.check()) is not None:
        target.problems.append(f"after the undecodable bytes: {problem}")
    return name, seen, grown


# -- processes ------------------------------------------------------------------------------
@contextlib.contextmanager
def child(cmd: list[str], eof_stops: bool) -> Iterator[tuple[subprocess.Popen, str, str]]:
    """Start ``cmd``; yield (process, address from its 'listening on' line, its stderr log)."""
    with tempfile.NamedTemporaryFile("w", prefix="fuzz-", suffix=".log") as log:
        proc = subprocess.Popen(cmd, stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=log,
                                text=True, env={**os.environ, "PYTHONUNBUFFERED": "1"})  # fmt: skip
        try:
            line = proc.stdout.readline().strip() if proc.stdout else ""
            if not line.startswith("listening on "):
                with open(log.name) as err:
                    raise RuntimeError(f"{shlex.join(cmd)}: {line!r} {err.read()[-600:]}")
            yield proc, line.removeprefix("listening on "), log.name
        finally:
            if proc.stdin:
                proc.stdin.close()  # --child servers stop on EOF (also if we die); `serve` on TERM
            with contextlib.suppress(subprocess.TimeoutExpired):
                proc.wait(timeout=10 if eof_stops else 0)
            if proc.poll() is None:
                proc.send_signal(signal.SIGTERM)
            try:
                proc.wait(timeout=20)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()


def serve_child(kind: str) -> None:
    """``--child manager|bare``: serve on a free loopback port until stdin closes."""
    if kind == "manager":
        from robogym_ray.supervision.manager_service import serve_manager
        from robogym_ray.supervision.spawners import InProcessSpawner
        from robogym_ray.supervision.supervisor import Supervisor, SupervisorConfig

        sup = Supervisor(SupervisorConfig(probe_interval_s=0), InProcessSpawner())
        server, port = serve_manager(sup, "127.0.0.1", 0)
    else:  # no code of ours on the request path: gRPC decodes, then the base class refuses
        server = grpc.server(futures.ThreadPoolExecutor(max_workers=10))  # as robot servers
        pb_grpc.add_RobotServerServicer_to_server(pb_grpc.RobotServerServicer(), server)
        port = server.add_insecure_port("127.0.0.1:0")
        server.start()
    print(f"listening on 127.0.0.1:{port}", flush=True)
    sys.stdin.read()
    if kind == "manager":
        sup.shutdown()
    server.stop(grace=None)


# -- phases and report ----------------------------------------------------------------------
def fuzz_robot(robot: str, args: argparse.Namespace, t_end: float,
               pool: futures.ThreadPoolExecutor, leaks: list) -> tuple[Target, int]:  # fmt: skip
    """Fuzz one robot server; returns it and how many round trips came back corrupted."""
    cmd = [sys.executable, "-m", "robogym_ray.cli", "serve", "--robot", robot,
           "--seed", str(args.seed), *ROBOTS[robot][0]]  # fmt: skip
    with child(cmd, eof_stops=False) as (proc, address, log):
        target = Target(robot, address, proc, log, state_len=ROBOTS[robot][2])
        before, _ = round_trip(target, robot)
        fuzz(target, partial(robot_message, robot=robot), args.messages, args, t_end, pool)
        if target.problems:
            return target, 0
        after, err = round_trip(target, robot)
        same = list(after.state) == list(before.state) and after.state_dict == before.state_dict
        if err > 0.0 or not same or target.check() is not None:
            target.problems.append(f"round trip: max |got - set| {err}, same as before: {same}")
            return target, 1
        if robot == "mir100" and args.leak_messages:
            leaks.append(leak(target, "MiR100 robot server (`robogym-ray serve`)", args, pool))
    return target, 0


def start_use_kill(target: Target, cmd: str) -> str | None:
    """A valid StartNewServer, a GetState at the new server, KillServer twice; None if all ok."""
    stub = sm_grpc.ServerManagerStub(target.channel)
    try:
        started = stub.StartNewServer(sm.RobotServer(cmd=cmd), timeout=60)
        if not started.success:
            return f"StartNewServer({cmd}) refused: {started.info}"
        with grpc.insecure_channel(f"127.0.0.1:{started.port}") as channel:
            state = pb_grpc.RobotServerStub(channel).GetState(pb.Empty(), timeout=10)
        if not state.success or not state.state or not np.all(np.isfinite(state.state)):
            return f"the started server's GetState: {len(state.state)} values"
        for _ in range(2):  # robo-gym's client kills twice (close and __del__): both succeed
            killed = stub.KillServer(sm.RobotServer(port=started.port), timeout=30)
            if not killed.success:
                return f"KillServer({started.port}) refused: {killed.info}"
    except grpc.RpcError as exc:
        return f"{exc.code().name}: {exc.details()}"
    return None


def fuzz_manager(args: argparse.Namespace, t_end: float,
                 pool: futures.ThreadPoolExecutor) -> tuple[Target, int]:  # fmt: skip
    with child([sys.executable, __file__, "--child", "manager"], True) as (proc, address, log):
        target = Target("manager", address, proc, log, prefix=SM)
        # The deliberate starts come first: the warm-up RSS sample includes their PyBullet.
        for i in range(args.manager_starts):
            if (problem := start_use_kill(target, (MIR_CMD, UR10_CMD)[i % 2])) is not None:
                target.problems.append(f"deliberate start {i}: {problem}")
        fuzz(target, manager_message, args.manager_messages, args, t_end, pool)
        if target.problems or (problem := start_use_kill(target, MIR_CMD)) is None:
            return target, 0
        target.problems.append(f"after fuzzing: {problem}")
        return target, 1


def report(rows: list[tuple[Target, int]], leaks: list) -> None:
    print(f"Run {time.strftime('%Y-%m-%d %H:%M %Z')} on `{platform.node()}`, {os.cpu_count()} "
          f"CPUs, python {platform.python_version()}, grpcio {grpc.__version__}:\n\n"
          f"    {shlex.join(['python', *sys.argv])}\n\n"
          "| target | messages | ok | refused (with reason) | refused, no reason | gRPC status "
          "codes | deadline exceeded | crashes | corrupted | RSS (MB) after warm-up -> half -> end "
          "| messages/s |\n|---|---|---|---|---|---|---|---|---|---|---|")  # fmt: skip
    for t, corrupted in rows:
        codes = ", ".join(f"{k} {v}" for k, v in sorted(t.outcomes.items())
                          if k not in ("ok", "refused", "refused_silently")) or "-"  # fmt: skip
        rss = " -> ".join(f"{t.rss[i]:.0f}" for i in (0, len(t.rss) // 2, -1)) if t.rss else "-"
        print(f"| {t.name} | {t.sent} | {t.outcomes['ok']} | {t.outcomes['refused']} | "
              f"{t.outcomes['refused_silently']} | {codes} | {len(t.hangs)} | "
              f"{len(t.problems) - corrupted} | {corrupted} | {rss} | "
              f"{t.sent / max(t.seconds, 1e-9):.0f} |")  # fmt: skip
    if leaks:
        print("\n| undecodable bytes sent to | messages | replies | RSS growth (MB) "
              "| MB per 10,000 |\n|---|---|---|---|---|")  # fmt: skip
    for name, seen, grown in leaks:
        replies = ", ".join(f"{k} {v}" for k, v in sorted(seen.items()))
        print(f"| {name} | {seen.total()} | {replies} | {grown:+.1f} | "
              f"{grown / max(seen.total(), 1) * 10_000:+.1f} |")  # fmt: skip
    for t, _ in rows:
        print(f"\n- {t.name}: RSS (MB) after each batch: {', '.join(f'{r:.0f}' for r in t.rss)}")
        for line in t.problems + [f"DEADLINE_EXCEEDED: {h}" for h in t.hangs]:
            print(f"\n- {t.name}: {line}")


def main() -> int:
    global MAX_TEXT  # noqa: PLW0603 - read deep inside the generators, by the worker threads
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--messages", type=int, default=10_000, help="per robot server")
    parser.add_argument("--manager-messages", type=int, default=2_000)
    parser.add_argument("--manager-starts", type=int, default=2, help="deliberate valid starts")
    parser.add_argument("--leak-messages", type=int, default=10_000, help="undecodable, each")
    parser.add_argument("--threads", type=int, default=8)
    parser.add_argument("--batches", type=int, default=10, help="checks; the first is warm-up")
    parser.add_argument("--seconds", type=float, default=1200.0, help="fuzzing time limit")
    parser.add_argument("--deadline", type=float, default=10.0, help="per call (s)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--max-text", type=int, default=MAX_TEXT, help="longest string sent")
    parser.add_argument("--child", choices=["manager", "bare"], help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        serve_child(args.child)
        return 0
    MAX_TEXT = args.max_text
    t_end, leaks = time.monotonic() + args.seconds, []
    with futures.ThreadPoolExecutor(args.threads) as pool:
        rows = [fuzz_robot(robot, args, t_end, pool, leaks) for robot in ROBOTS]
        rows.append(fuzz_manager(args, t_end, pool))
        if args.leak_messages:
            with child([sys.executable, __file__, "--child", "bare"], True) as (proc, addr, log):
                bare = Target("bare", addr, proc, log)
                leaks.append(leak(bare, "bare gRPC server, base servicer (no code of ours)",
                                  args, pool))  # fmt: skip
                leaks.append(leak(bare, "same, valid empty GetState (control)", args, pool, True))
    report(rows, leaks)
    if any(t.problems or t.hangs for t, _ in rows):
        return 1
    wanted = [args.messages, args.messages, args.manager_messages]
    return 2 if any(t.sent < n for (t, _), n in zip(rows, wanted, strict=True)) else 0


if __name__ == "__main__":
    sys.exit(main())
