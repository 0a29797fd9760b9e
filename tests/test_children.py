"""A child started through ``robogym_ray.children`` ends when its parent is stopped or killed,
as the processes the tests start do when the test run is stopped (SIGTERM) or killed."""

from __future__ import annotations

import importlib.util
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

pytestmark = pytest.mark.skipif(
    not sys.platform.startswith("linux"), reason="the parent-death signal is Linux's"
)

ROOT = Path(__file__).resolve().parents[1]


def child_start():
    """``benchmarks/child_start.py``: its live gRPC server and caller serve the test below."""
    spec = importlib.util.spec_from_file_location("child_start", ROOT / "benchmarks/child_start.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


PARENT = """
import sys, time
from robogym_ray import children
child = children.popen([sys.executable, "-c", "import time; time.sleep(600)"])
print(child.pid, flush=True)
time.sleep(600)
"""


def gone(pid: int) -> bool:
    """No such process, or a zombie waiting for whoever reaps orphans."""
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except FileNotFoundError:
        return True
    return state == "Z"


@pytest.mark.parametrize("stop", [signal.SIGTERM, signal.SIGKILL], ids=["SIGTERM", "SIGKILL"])
def test_a_child_ends_with_its_parent(stop: signal.Signals) -> None:
    parent = subprocess.Popen([sys.executable, "-c", PARENT], stdout=subprocess.PIPE, text=True)
    child = 0
    try:
        assert parent.stdout is not None
        child = int(parent.stdout.readline())
        assert not gone(child)
        os.kill(parent.pid, stop)
        assert parent.wait(timeout=60) == -stop
        # The kernel signals the child as the parent exits; the wait only covers the scheduling
        # of an orphan on a busy machine.
        deadline = time.monotonic() + 60
        while not gone(child) and time.monotonic() < deadline:
            time.sleep(0.01)
        assert gone(child), f"the child {child} outlived its parent"
    finally:
        if parent.poll() is None:
            parent.kill()
            parent.wait()
        if child and not gone(child):
            os.kill(child, signal.SIGKILL)


def test_children_of_a_process_with_live_grpc_calls_all_start() -> None:
    """grpc/grpc#43055: a child forked (``preexec_fn``) while this process has gRPC calls in
    flight could abort before its ``exec`` (``epoll_wait error: Bad file descriptor``): robo-gym's
    client in the compat tests died so once. 300 children, started beside a thread that keeps
    calling a real gRPC server on 127.0.0.1, must all run their program."""
    from robogym_ray import children

    with child_start().live_grpc_calls() as answered:
        ran = [children.run(["true"], capture_output=True, timeout=60) for _ in range(300)]
    failed = [(r.returncode, r.stderr[-300:]) for r in ran if r.returncode != 0]
    assert failed == [], failed
    assert len(answered) > 1 and all(answered)  # the thread's calls, past the first one


def test_a_childs_program_ignores_the_signals_a_subprocess_child_ignores() -> None:
    """The arming lines run in Python, which ignores SIGPIPE and SIGXFSZ; the program they
    exec gets them back, as ``subprocess`` gives them (``restore_signals``)."""
    from robogym_ray import children

    probe = ["grep", "-E", "^Sig(Ign|Blk)", "/proc/self/status"]
    ours = children.run(probe, capture_output=True, text=True, timeout=60)
    theirs = subprocess.run(probe, capture_output=True, text=True, timeout=60)
    assert ours.returncode == theirs.returncode == 0
    assert ours.stdout == theirs.stdout
