"""The robot server: robo-gym's ``RobotServer`` gRPC service in front of a simulated robot.

``RobotServerCore`` is the plain-Python logic (no gRPC) so it can be benchmarked and tested
in-process; ``RobotServerServicer`` adapts it to the wire; ``start_robot_server`` builds both.

Error convention (robo-gym's, see docs/protocol.md): a call with bad input (wrong length, NaN/inf,
out of range, unknown keys) is answered normally with ``success=false`` - exactly what robo-gym's
ROS servers do, so robo-gym's own client raises its usual errors - and the reason travels in the
trailing metadata key ``robogym-error`` (State replies also carry it as
``string_params["error"]``). Nothing in the simulation changes and the server keeps serving.
"""

from __future__ import annotations

import logging
import threading
import time
import traceback
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import grpc
import numpy as np

from robogym_ray.config import check_port
from robogym_ray.errors import BindError, ConfigError, InvalidActionError, RoboGymRayError
from robogym_ray.protocol import robot_server_pb2 as pb
from robogym_ray.protocol import robot_server_pb2_grpc as pb_grpc
from robogym_ray.protocol.tls import ServerTls
from robogym_ray.robots.base import RobotArguments, SimRobot, StateRequest, StateSnapshot
from robogym_ray.robots.command_handler import CommandHandler
from robogym_ray.robots.ports import check_port_free, grpc_server, listen
from robogym_ray.robots.registry import make_robot
from robogym_ray.robots.state_buffer import StateBuffer
from robogym_ray.text import clip_text

if TYPE_CHECKING:
    from robogym_ray.robots.emulation import EmulationConfig
    from robogym_ray.robots.hardware import HardwareConfig

log = logging.getLogger(__name__)

SHUTDOWN_CONFIRM_S = 5.0  # how long past its grace a stop waits for gRPC's confirmation

ERROR_METADATA_KEY = "robogym-error"
TOKEN_METADATA_KEY = "robogym-token"


class RobotServerCore:
    """Serialises access to one robot, runs its command handler and keeps its state buffer.

    Simulated time (default): each SendAction runs one action cycle of actuation ticks and
    physics *now*, so simulation runs as fast as the CPU allows. Real-time pacing
    (``real_time=True``, for real robots' emulation): a background loop ticks the handler at
    the actuation rate against the wall clock, sensors refresh at their own rates, and
    SendAction returns after one action cycle, as robo-gym's ROS servers do.
    """

    def __init__(self, robot: SimRobot, *, real_time: bool = False) -> None:
        self.robot = robot
        self.real_time = real_time
        self.handler = CommandHandler(robot.handler_config, robot.publish)
        self.buffer = StateBuffer()
        self.sim_time = 0.0
        self.calls: dict[str, int] = {"get": 0, "set": 0, "action": 0, "rejected": 0}
        self._lock = threading.RLock()  # PyBullet is not thread-safe; gRPC calls are concurrent
        self._stop = threading.Event()
        self._last_refresh: dict[str, float] = {}
        self.buffer.update(**robot.read_sensors())
        self._loop: threading.Thread | None = None
        if real_time:
            self._loop = threading.Thread(target=self._real_time_loop, daemon=True)
            self._loop.start()

    # -- RPC semantics ----------------------------------------------------------------------
    def get_state(self) -> StateSnapshot:
        """The latest consistent snapshot; a pure read that never waits on the simulation."""
        self.calls["get"] += 1
        _, groups = self.buffer.snapshot()
        return self.robot.compose(groups)

    def set_state(self, request: StateRequest) -> None:
        """Reset robot and scene; returns when the new state is in place (and in the buffer)."""
        with self._lock:
            self.robot.set_state(request)  # validates first: raises before changing anything
            self.handler.clear()
            self.buffer.update(**self.robot.read_sensors())
        self.calls["set"] += 1

    def send_action(self, action: Sequence[float] | np.ndarray) -> bool:
        """Apply one action for one action cycle; returns whether the handler accepted it."""
        command = self.robot.validate_action(_as_vector(action))
        self.calls["action"] += 1
        if self.real_time:
            accepted = self.handler.submit(command)
            time.sleep(self.robot.handler_config.action_cycle)
            return accepted
        with self._lock:
            accepted = self.handler.submit(command)
            cfg = self.robot.handler_config
            for _ in range(cfg.ticks_per_action):
                self._tick(cfg.actuation_cycle)
            self.buffer.update(**self.robot.read_sensors())
        return accepted

    def send_action_get_state(self, action: Sequence[float] | np.ndarray) -> StateSnapshot:
        self.send_action(action)
        return self.get_state()

    def get_arguments(self) -> RobotArguments:
        """What the robot was launched with (GetArguments); a pure read."""
        return self.robot.arguments()

    def recover(self) -> None:
        """RecoverFromErrors: a hardware robot clears its errors (raises if it cannot); a
        simulated one has none. The handler's queue is dropped: nothing stale moves the arm."""
        with self._lock:
            self.robot.recover()
            self.handler.clear()
            self.buffer.update(**self.robot.read_sensors())

    def close(self) -> None:
        self._stop.set()
        if self._loop is not None:
            self._loop.join(timeout=2.0)
        with self._lock:
            self.robot.close()

    # -- internals --------------------------------------------------------------------------
    def _tick(self, dt: float) -> None:
        self.handler.tick()
        self.robot.advance(dt)
        self.sim_time += dt

    def _real_time_loop(self) -> None:
        dt = self.robot.handler_config.actuation_cycle
        periods = dict(self.robot.sensor_periods)
        next_tick = time.monotonic()
        while not self._stop.is_set():
            with self._lock:
                self._tick(dt)
                due = [g for g, period in periods.items() if self._due(g, period)]
                fresh = self.robot.read_sensors()
                # Slow sensors keep their last value until their period has passed.
                self.buffer.update(
                    **{g: v for g, v in fresh.items() if g not in periods or g in due}
                )
            next_tick += dt
            delay = next_tick - time.monotonic()
            if delay > 0:
                self._stop.wait(delay)
            else:  # fell behind (slow machine): resynchronise rather than burst to catch up
                next_tick = time.monotonic()

    def _due(self, group: str, period: float) -> bool:
        last = self._last_refresh.get(group, -np.inf)
        if self.sim_time - last >= period - 1e-9:
            self._last_refresh[group] = self.sim_time
            return True
        return False


def _as_vector(values: Sequence[float] | np.ndarray) -> np.ndarray:
    try:
        vec = np.asarray(values, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise InvalidActionError(f"action is not a list of numbers: {exc}") from None
    if vec.ndim != 1:
        raise InvalidActionError(f"action must be a flat list, got shape {vec.shape}")
    return vec


# -- wire adapters --------------------------------------------------------------------------
def snapshot_to_msg(snapshot: StateSnapshot) -> pb.State:
    msg = pb.State(success=True)
    msg.state.extend(np.asarray(snapshot.state, dtype=np.float32).tolist())
    if snapshot.state_dict:
        msg.state_dict.update({k: float(v) for k, v in snapshot.state_dict.items()})
    return msg


def arguments_to_msg(args: RobotArguments) -> pb.Arguments:
    return pb.Arguments(
        action_cycle_rate=args.action_cycle_rate,
        rs_mode=args.rs_mode,
        action_mode=args.action_mode,
        success=True,
    )


def msg_to_request(msg: pb.State) -> StateRequest:
    return StateRequest(
        state=np.asarray(msg.state, dtype=np.float64),
        state_dict=dict(msg.state_dict),
        float_params=dict(msg.float_params),
        string_params=dict(msg.string_params),
    )


class RobotServerServicer(pb_grpc.RobotServerServicer):
    """robo-gym's RobotServer service over a ``RobotServerCore``."""

    def __init__(self, core: RobotServerCore) -> None:
        self.core = core
        self._log_limit = LogLimit()

    def GetState(self, request: pb.Empty, context: grpc.ServicerContext) -> pb.State:  # noqa: N802
        try:
            return snapshot_to_msg(self.core.get_state())
        except Exception as exc:  # noqa: BLE001 - robo-gym convention: never a gRPC error
            return self._fail_state(context, "GetState", exc)

    def SetState(self, request: pb.State, context: grpc.ServicerContext) -> pb.Success:  # noqa: N802
        try:
            self.core.set_state(msg_to_request(request))
            return pb.Success(success=True)
        except Exception as exc:  # noqa: BLE001
            self._report(context, "SetState", exc)
            return pb.Success(success=False)

    def SendAction(self, request: pb.Action, context: grpc.ServicerContext) -> pb.Success:  # noqa: N802
        try:
            return pb.Success(success=self.core.send_action(request.action))
        except Exception as exc:  # noqa: BLE001
            self._report(context, "SendAction", exc)
            return pb.Success(success=False)

    def SendActionGetState(self, request: pb.Action, context: grpc.ServicerContext) -> pb.State:  # noqa: N802
        try:
            return snapshot_to_msg(self.core.send_action_get_state(request.action))
        except Exception as exc:  # noqa: BLE001
            return self._fail_state(context, "SendActionGetState", exc)

    def GetArguments(self, request: pb.Empty, context: grpc.ServicerContext) -> pb.Arguments:  # noqa: N802
        try:
            return arguments_to_msg(self.core.get_arguments())
        except Exception as exc:  # noqa: BLE001
            self._report(context, "GetArguments", exc)
            return pb.Arguments(success=False)

    def RecoverFromErrors(self, request: pb.Empty, context: grpc.ServicerContext) -> pb.Success:  # noqa: N802
        try:
            self.core.recover()
            return pb.Success(success=True)
        except Exception as exc:  # noqa: BLE001
            self._report(context, "RecoverFromErrors", exc)
            return pb.Success(success=False)

    def _fail_state(self, context: grpc.ServicerContext, rpc: str, exc: Exception) -> pb.State:
        message = self._report(context, rpc, exc)
        return pb.State(success=False, string_params={"error": message})

    def _report(self, context: grpc.ServicerContext, rpc: str, exc: Exception) -> str:
        message = reject(self.core, self._log_limit, rpc, exc)
        context.set_trailing_metadata(((ERROR_METADATA_KEY, ascii_safe(message)),))
        return message


def reject(core: RobotServerCore, log_limit: LogLimit, rpc: str, exc: Exception) -> str:
    """Count, log (rate-limited) and word a call refused with ``success=false``; returns the
    message. The one wording of a refusal, for the gRPC servicer and the in-process client."""
    core.calls["rejected"] += 1
    # Client input may be megabytes long: cut once, then use the cut text everywhere.
    message = clip_text(f"{rpc}: {type(exc).__name__}: {exc}")
    suppressed = log_limit.allow((rpc, type(exc).__name__))
    if suppressed is not None:
        note = f" ({suppressed} similar suppressed)" if suppressed else ""
        if isinstance(exc, RoboGymRayError):
            log.warning("rejected %s%s", message, note)
        else:  # a bug of ours, not bad input: keep the traceback (frames only: bounded)
            frames = "".join(traceback.format_tb(exc.__traceback__))
            log.error("failed %s%s\nTraceback:\n%s", message, note, frames)
    return message


def ascii_safe(message: str) -> str:
    """gRPC metadata values must be printable ASCII."""
    return message.encode("ascii", "replace").decode("ascii")


class LogLimit:
    """At most ``burst`` log lines per kind of failure per ``window_s``; counts the rest.

    A client that repeats one bad call in a loop would otherwise fill the log with one line
    per call; the first line after a quiet window says how many were left out. ``clock``:
    monotonic seconds (a test moves its own).
    """

    def __init__(
        self, burst: int = 10, window_s: float = 60.0, clock: Callable[[], float] = time.monotonic
    ) -> None:
        self.burst, self.window_s, self.clock = burst, window_s, clock
        self._lock = threading.Lock()
        self._windows: dict[tuple[str, str], tuple[float, int, int]] = {}
        """kind -> (window start, lines logged in it, lines suppressed since the last one)"""

    def allow(self, kind: tuple[str, str]) -> int | None:
        """None: do not log; else log, noting this many suppressed lines since the last one."""
        now = self.clock()
        with self._lock:
            start, logged, suppressed = self._windows.get(kind, (now, 0, 0))
            if now - start >= self.window_s:
                start, logged = now, 0
            if logged >= self.burst:
                self._windows[kind] = (start, logged, suppressed + 1)
                return None
            self._windows[kind] = (start, logged + 1, 0)
            return suppressed


class _TokenInterceptor(grpc.ServerInterceptor):
    """Refuses calls without the shared token (only used when listening beyond loopback)."""

    def __init__(self, token: str) -> None:
        self._token = token

        def deny(request: object, context: grpc.ServicerContext) -> None:
            context.abort(grpc.StatusCode.UNAUTHENTICATED, f"missing or wrong {TOKEN_METADATA_KEY}")

        self._deny = grpc.unary_unary_rpc_method_handler(deny)

    def intercept_service(self, continuation, handler_call_details):  # type: ignore[no-untyped-def]
        metadata = dict(handler_call_details.invocation_metadata or ())
        if metadata.get(TOKEN_METADATA_KEY) == self._token:
            return continuation(handler_call_details)
        return self._deny


@dataclass
class RobotServerHandle:
    """A running robot server: its address, its core, and how to stop it."""

    server: grpc.Server
    core: RobotServerCore
    host: str
    port: int

    @property
    def address(self) -> str:
        host = f"[{self.host}]" if ":" in self.host else self.host
        return f"{host}:{self.port}"

    def stop(self, grace: float = 0.5) -> None:
        """Stop serving (running calls get ``grace`` seconds), then close the robot (a real arm
        comes to rest): gRPC's confirmation is awaited for a bounded time, never forever."""
        confirm_s = grace + SHUTDOWN_CONFIRM_S
        if not self.server.stop(grace).wait(timeout=confirm_s):
            log.warning("gRPC did not confirm the server's shutdown in %.1f s; closing the robot "
                        "anyway", confirm_s)  # fmt: skip
        self.core.close()

    def wait(self, timeout: float | None = None) -> bool:
        """Block until the server stops (or ``timeout`` seconds pass); whether it stopped.
        Anything raised meanwhile (Ctrl-C's KeyboardInterrupt) stops the server and closes the
        robot before it propagates, so a real arm comes to rest. A foreground process that must
        also end on SIGTERM installs ``foreground.StopSignals``, as ``serve`` does."""
        try:
            return not self.server.wait_for_termination(timeout)  # gRPC's True means timed out
        except BaseException:
            self.stop()
            raise


def start_robot_server(
    robot: str,
    *,
    scene: str | None = None,
    seed: int | None = None,
    options: Mapping[str, str] | None = None,
    host: str = "127.0.0.1",
    port: int = 0,
    real_time: bool = False,
    token: str | None = None,
    max_workers: int = 10,
    emulation: EmulationConfig | None = None,
    tls: ServerTls | None = None,
    hardware: HardwareConfig | None = None,
) -> RobotServerHandle:
    """Build the robot and serve it on ``host:port`` (port 0 = a free port); returns at once.

    ``emulation`` serves an emulated real robot (latency, noise, dynamics differences; see
    ``robots.emulation``) instead of the plain simulation. ``tls`` (``protocol.tls.server_tls``)
    serves it over TLS; without, on a plain port as robo-gym's servers do. ``hardware`` serves
    the real robot through one of its card's backends (``robots.hardware``), always paced by
    the wall clock.
    """
    # Before the robot is built: nothing to undo, and no PyBullet banner before the error.
    check_port(port, "robot server port")
    check_port_free(host, port, "robot server port")
    if hardware is not None:
        if emulation is not None:
            raise ConfigError("a hardware robot cannot also be emulated: drop --emulate-hardware")
        from robogym_ray.robots.hardware import make_hardware_robot

        real_time = True
        sim_robot: SimRobot = make_hardware_robot(robot, options or {}, hardware)
    else:
        sim_robot = make_robot(robot, scene=scene, seed=seed, options=options)
    if emulation is not None:
        from robogym_ray.robots.emulation import emulate

        sim_robot = emulate(sim_robot, emulation, seed=seed)
    core = RobotServerCore(sim_robot, real_time=real_time)
    interceptors = [_TokenInterceptor(token)] if token else []
    server = grpc_server(max_workers, interceptors)
    pb_grpc.add_RobotServerServicer_to_server(RobotServerServicer(core), server)
    try:
        bound = listen(server, host, port, "robot server port", tls.credentials() if tls else None)
    except BindError:
        core.close()
        raise
    server.start()
    return RobotServerHandle(server=server, core=core, host=host, port=bound)
