"""franky-sim, a MuJoCo FR3 that speaks libfranka's network protocol, as a child process.

The tests, the tracking benchmark and the sim-to-sim experiment drive the Franka backend
(``franky_arm``) against it exactly as against a real FR3: through libfranka's TCP/UDP protocol.
franky-sim binds its fixed ports (1337 command, 1338 gripper) on a loopback *address* of its own
(``--hostname``), so each simulator gets a fresh address in 127.0.0.0/8 instead of a free port;
several can run side by side. This module imports neither franky nor franky-sim: the child
process does.
"""

from __future__ import annotations

import os
import random
import signal
import socket
import subprocess
import sys
import threading
import time

from robogym_ray import children
from robogym_ray.errors import ConfigError

FCI_PORTS = (1337, 1338)
"""libfranka's command port and the gripper's: what franky-sim binds on its address."""
READY_LINE = "Connect to the server using"
"""What franky-sim prints once it listens."""


def free_loopback_host(rng: random.Random | None = None, tries: int = 50) -> str:
    """A 127.x.y.z address (x >= 1, so never 127.0.0.1) whose FCI ports nothing holds."""
    rng = rng or random.Random()
    for _ in range(tries):
        host = f"127.{rng.randint(1, 254)}.{rng.randint(0, 255)}.{rng.randint(1, 254)}"
        if all(_port_free(host, port) for port in FCI_PORTS):
            return host
    raise ConfigError(f"no free loopback address for franky-sim after {tries} tries")


def _port_free(host: str, port: int) -> bool:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as probe:
        try:
            probe.bind((host, port))
        except OSError:
            return False
    return True


class FrankySim:
    """``python -m franky_sim.run_server -s mujoco --hostname HOST``, started and stopped by PID.

    The child runs in a process group of its own and gets SIGKILL if this process dies
    (``PR_SET_PDEATHSIG`` on Linux), so a killed test run leaves no simulator behind.
    """

    def __init__(self, host: str | None = None, start_timeout_s: float = 60.0) -> None:
        self.host = host or free_loopback_host()
        self.start_timeout_s = start_timeout_s
        self.proc: subprocess.Popen[str] | None = None
        self.log: list[str] = []

    def start(self) -> FrankySim:
        """Start the simulator; returns once it listens (ConfigError if it does not)."""
        cmd = [sys.executable, "-m", "franky_sim.run_server", "-s", "mujoco",
               "--hostname", self.host]  # fmt: skip
        env = {**os.environ, "PYTHONUNBUFFERED": "1"}
        self.proc = children.popen(
            cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=env,
            start_new_session=True, death_signal=signal.SIGKILL,
        )  # fmt: skip
        ready = threading.Event()
        threading.Thread(target=self._read, args=(self.proc, ready), daemon=True).start()
        end = time.monotonic() + self.start_timeout_s
        while not ready.wait(0.05):
            if self.proc.poll() is not None or time.monotonic() > end:
                self.kill()
                tail = " | ".join(self.log[-5:])
                raise ConfigError(f"franky-sim did not start on {self.host}: {tail!r}")
        return self

    def _read(self, proc: subprocess.Popen[str], ready: threading.Event) -> None:
        assert proc.stdout is not None
        for line in proc.stdout:
            self.log.append(line.rstrip())
            if READY_LINE in line:
                ready.set()

    def kill(self) -> None:
        """SIGKILL, as a crash or a pulled cable would end it."""
        self._signal(signal.SIGKILL)

    def stop(self) -> None:
        """SIGTERM (Ctrl-C's path), then SIGKILL if it lingers."""
        self._signal(signal.SIGTERM, then_kill_after_s=10.0)

    def _signal(self, sig: signal.Signals, then_kill_after_s: float | None = None) -> None:
        proc = self.proc
        if proc is None or proc.poll() is not None:
            return
        os.killpg(proc.pid, sig)  # its own group: the simulator and nothing else
        try:
            proc.wait(timeout=then_kill_after_s or 10.0)
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()

    def __enter__(self) -> FrankySim:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()
