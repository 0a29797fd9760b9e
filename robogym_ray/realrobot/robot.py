"""A real robot joined by address: checked, filtered, paused on trouble, never restarted.

Somebody else runs the robot server (ours with ``--real-time``, or robo-gym's ROS servers); this
class only connects to it. Unlike a simulation, a robot that failed may be in an unknown physical
state, so nothing here restarts or resets it: on any error or emergency stop it marks itself
**paused** and refuses every command until an operator calls ``resume()`` (from the CLI:
``robogym-ray resume-robot NAME``), which first checks that the server answers again. Other
robots and simulations are unaffected. Every action passes a ``SafetyFilter`` (see
``realrobot/safety.py``).
"""

from __future__ import annotations

import logging
import math
import os
import threading
import time
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from robogym_ray.errors import RobotServerError
from robogym_ray.protocol import robot_server_pb2 as pb
from robogym_ray.protocol.client import Deadlines, RobotServerClient
from robogym_ray.realrobot.safety import SafetyConfig, SafetyFilter

log = logging.getLogger(__name__)


def state_to_dict(msg: pb.State) -> dict[str, Any]:
    return {
        "state": list(msg.state),
        "state_dict": dict(msg.state_dict),
        "float_params": dict(msg.float_params),
        "string_params": dict(msg.string_params),
    }


class RobotPausedError(RobotServerError):
    """The real robot is paused; an operator must resume it."""


class RealRobot:
    """Gatekeeper of one real robot's server.

    Args:
        name: the robot's name (the Ray actor's name; what ``robogym-ray resume-robot`` takes).
        address: ``host:port`` of its robot server.
        safety: limits every action must respect.
        deadlines: per-RPC deadlines (robo-gym's by default: real robots are slow).
        token: shared token for the server, if it wants one.
        tls_ca: PEM of the CA of its server's TLS certificate (bytes or a file's path); None =
            a plain channel.
        check: probe the server once now (raises RobotServerError if it does not answer).
        probe_interval_s: when > 0, a background probe (GetState) runs whenever the robot has
            gone this long without a command, so a server that dies while nobody commands it
            pauses the robot then, not at the next command; 0 = probe only on request.
    """

    def __init__(
        self,
        name: str,
        address: str,
        safety: SafetyConfig,
        deadlines: Deadlines | None = None,
        token: str | None = None,
        check: bool = True,
        probe_interval_s: float = 0.0,
        tls_ca: str | os.PathLike | bytes | None = None,
    ) -> None:
        if not (math.isfinite(probe_interval_s) and probe_interval_s >= 0):
            raise ValueError(f"probe_interval_s = {probe_interval_s!r}; expected >= 0")
        self.name = name
        self.address = address
        self.safety = SafetyFilter(safety)
        self.client = RobotServerClient(address, deadlines=deadlines, token=token, tls_ca=tls_ca)
        self.paused = False
        self.pause_reason = ""
        self.paused_at = 0.0
        self.pauses = 0
        self._lock = threading.Lock()  # one command at a time, as on the pendant
        self.idle_probes = 0
        self._last_answer = time.monotonic()
        self._closed = threading.Event()
        if check:
            self.client.get_state()
        if probe_interval_s > 0:
            threading.Thread(
                target=self._watch, args=(probe_interval_s,), name=f"probe-{name}", daemon=True
            ).start()

    # -- commands (refused while paused) -----------------------------------------------------
    # Plain lists/dicts in and out: protobuf messages do not pickle across Ray.
    def get_state(self) -> dict[str, Any]:
        """GetState as ``{"state": [...], "state_dict": {...}, ...}``."""
        return state_to_dict(self._guarded("GetState", self.client.get_state))

    def set_state(
        self,
        state: Sequence[float] = (),
        state_dict: Mapping[str, float] | None = None,
        float_params: Mapping[str, float] | None = None,
        string_params: Mapping[str, str] | None = None,
    ) -> None:
        msg = pb.State(
            state=list(state),
            state_dict=dict(state_dict or {}),
            float_params=dict(float_params or {}),
            string_params=dict(string_params or {}),
        )
        self._guarded("SetState", self.client.set_state, msg)
        self.safety.reset()

    def send_action(self, action: Sequence[float] | np.ndarray) -> list[float]:
        """Send the filtered action; returns what was actually sent (clipped or not)."""
        safe = self.safety.filter(action)  # a refused command raises before anything is sent
        self._guarded("SendAction", self.client.send_action, safe)
        return safe.tolist()

    def send_action_get_state(self, action: Sequence[float] | np.ndarray) -> dict[str, Any]:
        safe = self.safety.filter(action)
        reply = self._guarded("SendActionGetState", self.client.send_action_get_state, safe)
        return state_to_dict(reply)

    def get_arguments(self) -> dict[str, Any] | None:
        """GetArguments as a plain dict (rate and modes), None from a server without it: what
        the env checks before its first reset, relayed (a read; it pauses nothing)."""
        args = self.client.get_arguments()
        if args is None:
            return None
        return {"action_cycle_rate": args.action_cycle_rate, "rs_mode": args.rs_mode,
                "action_mode": args.action_mode}  # fmt: skip

    # -- supervision ----------------------------------------------------------------------------
    def check(self) -> bool:
        """Health probe: GetState; a failure pauses the robot. Returns whether it is running."""
        if self.paused:
            return False
        try:
            self.get_state()
        except RobotServerError:
            return False
        return True

    def emergency_stop(self, reason: str = "emergency stop") -> None:
        """Pause now. Nothing is sent: a 'stop' command is robot-specific (a zero joint target
        would move a UR arm), so stopping the hardware is left to its own controller."""
        self._pause(reason)

    def resume(self, wait_s: float = 10.0) -> dict[str, Any]:
        """Operator's resume: ask the server to recover the robot from its errors, then un-pause
        once it answers a health check (both tried for up to ``wait_s``: gRPC backs off before
        reconnecting to an address that failed), else stay paused and raise RobotPausedError."""
        end = time.monotonic() + wait_s
        with self._lock:
            while True:
                try:
                    # A hardware server clears its arm's errors first (libfranka's
                    # recover_from_errors); robo-gym's servers have nothing to call.
                    self.client.recover_from_errors()
                    self.client.get_state()
                    break
                except RobotServerError as exc:
                    if time.monotonic() >= end:
                        raise RobotPausedError(
                            f"robot {self.name!r} stays paused: health check failed: {exc}",
                            address=self.address,
                            cause="paused",
                        ) from None
                    time.sleep(0.2)
            self._last_answer = time.monotonic()
            self.paused, self.pause_reason = False, ""
            self.safety.reset()
        log.warning("real robot %s resumed by operator", self.name)
        return self.status()

    def status(self) -> dict[str, Any]:
        return {
            "name": self.name,
            "address": self.address,
            "paused": self.paused,
            "reason": self.pause_reason,
            "paused_at": self.paused_at,
            "pauses": self.pauses,
            "clipped": self.safety.clipped,
            "refused": self.safety.refused,
            "idle_probes": self.idle_probes,
            "last_answer_s_ago": round(time.monotonic() - self._last_answer, 3),
        }

    def close(self) -> None:
        self._closed.set()
        self.client.close()

    # -- internals -----------------------------------------------------------------------------
    def _guarded(self, rpc: str, call: Any, *args: Any) -> Any:
        with self._lock:
            if self.paused:
                raise RobotPausedError(
                    f"robot {self.name!r} is paused ({self.pause_reason}); {rpc} not sent; "
                    f"an operator must run `robogym-ray resume-robot {self.name}`",
                    address=self.address,
                    cause="paused",
                )
            try:
                reply = call(*args)
            except RobotServerError as exc:
                self._pause(f"{rpc} failed: {exc}")
                raise
            self._last_answer = time.monotonic()
            return reply

    def _watch(self, interval_s: float) -> None:
        # A paused robot is left alone: only an operator's resume may probe it back to life.
        while not self._closed.wait(interval_s / 2):
            if not self.paused and time.monotonic() - self._last_answer >= interval_s:
                self.idle_probes += 1
                if not self.check():
                    log.error("real robot %s failed its idle probe", self.name)

    def _pause(self, reason: str) -> None:
        # No lock: an emergency stop must not wait for a command in flight to time out.
        if not self.paused:
            self.paused, self.pause_reason, self.paused_at = True, reason, time.time()
            self.pauses += 1
            log.error("real robot %s paused: %s", self.name, reason)
