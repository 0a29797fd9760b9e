"""The embedded Ray listens on loopback only.

Each case starts its own Ray in a child process (the suite's shared Ray is already up in this
one; the two children run side by side), runs one actor so that a core worker listens too, and
lists every listening TCP socket of that child's descendants from /proc. The plain ``ray.init``
case is the defect as Ray 2.60 ships it: it shows that the scan sees Ray's ``*:port`` listeners
at all.
"""

from __future__ import annotations

import contextlib
import ipaddress
import json
import os
import subprocess
import sys
import tempfile
from collections.abc import Iterator
from pathlib import Path

import pytest

from robogym_ray import children

pytestmark = [
    pytest.mark.ray,
    pytest.mark.skipif(not Path("/proc/net/tcp").exists(), reason="reads Linux's /proc"),
]


def _is_loopback(text: str) -> bool:
    ip = ipaddress.ip_address(text)
    mapped = getattr(ip, "ipv4_mapped", None)  # ::ffff:127.0.0.1 from an IPv6 socket
    return ip.is_loopback or (mapped is not None and mapped.is_loopback)


_CHILD = r"""
import json, os, sys
from pathlib import Path
import ray
from robogym_ray.distributed.local_ray import start_local_ray

def descendants(root):
    children = {}
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        children.setdefault(int(fields[1]), []).append(int(stat.parent.name))
    found, todo = [], [root]
    while todo:
        pid = todo.pop()
        found.append(pid)
        todo.extend(children.get(pid, []))
    return found

def socket_inodes(pid):
    inodes = set()
    try:
        for fd in Path(f"/proc/{pid}/fd").iterdir():
            target = os.readlink(fd)
            if target.startswith("socket:["):
                inodes.add(target[8:-1])
    except OSError:
        pass
    return inodes

def address(hex_ip):
    raw = bytes.fromhex(hex_ip)
    if len(raw) == 4:
        return ".".join(str(b) for b in raw[::-1])
    words = [raw[i:i + 4][::-1] for i in range(0, 16, 4)]
    import ipaddress
    return str(ipaddress.IPv6Address(b"".join(words)))

def listeners(pids):
    inodes = set().union(*(socket_inodes(p) for p in pids))
    found = []
    for table in ("/proc/net/tcp", "/proc/net/tcp6"):
        for line in Path(table).read_text().splitlines()[1:]:
            cols = line.split()
            if cols[3] == "0A" and cols[9] in inodes:  # 0A: LISTEN
                ip, port = cols[1].split(":")
                found.append([address(ip), int(port, 16)])
    return found

kwargs = dict(_temp_dir=sys.argv[2], include_dashboard=False, log_to_driver=False,
              logging_level="ERROR")
if sys.argv[1] == "ours":
    node = start_local_ray(1, **kwargs)
else:
    ray.init(num_cpus=1, **kwargs)
    node = ray.util.get_node_ip_address()

@ray.remote(num_cpus=0.1)
class Probe:
    def pid(self):
        return os.getpid()

probe = Probe.remote()
worker_pid = ray.get(probe.pid.remote())
pids = descendants(os.getpid())
print(json.dumps({"node": node, "worker_in_tree": worker_pid in pids,
                  "listeners": listeners(pids)}))
ray.shutdown()
"""


@pytest.fixture(scope="module")
def listeners() -> Iterator[dict[str, dict]]:
    """{mode: what its child saw} for both modes, the two children run side by side (most of a
    Ray's start is waiting on its own processes, so two overlap well on 2 cores)."""
    env = {**os.environ, "RAY_ADDRESS": ""}
    env.pop("RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER", None)
    # Short paths under /tmp (Ray's socket paths), removed with the sessions' files after.
    with contextlib.ExitStack() as stack:
        procs = {}
        for mode in ("ours", "plain"):
            temp_dir = stack.enter_context(tempfile.TemporaryDirectory(prefix="rgl", dir="/tmp"))
            procs[mode] = children.popen(
                [sys.executable, "-c", _CHILD, mode, temp_dir],
                stdout=subprocess.PIPE,
                stderr=subprocess.PIPE,
                text=True,
                env=env,
            )
        seen = {}
        try:
            for mode, proc in procs.items():
                stdout, stderr = proc.communicate(timeout=180)
                assert proc.returncode == 0, f"{mode}: {stderr[-3000:]}"
                seen[mode] = json.loads(stdout.strip().splitlines()[-1])
        finally:
            for proc in procs.values():
                if proc.poll() is None:
                    proc.kill()
                    proc.wait()
    yield seen


def test_the_embedded_ray_listens_on_loopback_only(listeners: dict[str, dict]) -> None:
    seen = listeners["ours"]
    assert seen["node"] == "127.0.0.1"
    assert seen["worker_in_tree"], "the actor's worker was not found among Ray's processes"
    # GCS, raylet (node manager + object manager), the core workers, the agents.
    assert len(seen["listeners"]) >= 4, seen
    exposed = [(ip, port) for ip, port in seen["listeners"] if not _is_loopback(ip)]
    assert exposed == [], f"listening beyond loopback: {exposed}"


def test_plain_ray_init_listens_on_every_interface(listeners: dict[str, dict]) -> None:
    # Documents why start_local_ray exists; if a later Ray binds loopback on its own, this is
    # the test to drop (and start_local_ray's switch may be dropped with it).
    seen = listeners["plain"]
    exposed = [ip for ip, _ in seen["listeners"] if not _is_loopback(ip)]
    assert exposed, seen


def test_join_ray_takes_the_loopback_road_only_for_a_loopback_only_listener() -> None:
    import socket

    from robogym_ray.distributed.local_ray import _loopback_only, routable_ip

    if routable_ip() == "127.0.0.1":
        pytest.skip("this machine has no routable address to tell the two apart")
    assert not _loopback_only("10.0.0.5:6379")  # a cluster elsewhere: Ray's usual road
    assert not _loopback_only("auto")
    for bind, loopback_only in (("127.0.0.1", True), ("0.0.0.0", False)):
        with socket.socket() as listener:
            listener.bind((bind, 0))
            listener.listen()
            port = listener.getsockname()[1]
            assert _loopback_only(f"127.0.0.1:{port}") is loopback_only, bind
            assert _loopback_only(f"localhost:{port}") is loopback_only, bind
