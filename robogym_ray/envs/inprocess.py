"""In-process simulation: a Sim env drives its robot core in its own process, without the wire.

``InProcessServerProvider`` (the default of every Sim env, and of simulated training workers)
builds the same ``RobotServerCore`` a robot server would serve and hands the env an
``InProcessClient`` with the surface and the semantics of ``RobotServerClient``:

* the same validation: actions are checked (shape, NaN, inf) and travel as float32, as on the
  wire; the core validates them and SetState requests exactly as behind gRPC;
* the same state: replies are the ``State`` messages the servicer would send, so a seeded
  episode gives the same states both ways (``tests/envs/test_inprocess.py`` compares them);
* the same errors: a refused call raises ``RobotServerError(cause="rejected")`` with the
  servicer's wording (``robots.server.reject``).

Faults stay supervised, by the provider instead of the supervisor actor: a call that raises
inside the simulation is refused (the env then rebuilds the sim); a call that returns after its
deadline raises ``cause="deadline"``; a state with NaN/inf or a value beyond ``state_limit``
raises ``cause="invalid_state"``. ``report_fault`` counts the restart by cause against the
supervisor's ``RestartPolicy`` (backoff, give-up limit) and the env's next ``acquire`` builds a
fresh core. A call that never returns (a simulation stuck in a physics step) cannot be cut off
from inside its own thread: the training loop's worker deadline replaces the whole worker
(``TrainConfig.worker_deadline_s``).

The gRPC path stays one option away: pass ``provider=EmbeddedServerProvider()`` (a robot server
in this process on a loopback port) or ``rs_address=`` / a supervisor's provider.
"""

from __future__ import annotations

import itertools
import logging
import time
from collections import Counter
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from robogym_ray.errors import RobotServerError
from robogym_ray.protocol import robot_server_pb2 as pb
from robogym_ray.protocol.client import Deadlines, check_action, deadline_error
from robogym_ray.supervision.health import check_state
from robogym_ray.supervision.restart_policy import RestartBook, RestartPolicy

if TYPE_CHECKING:
    from robogym_ray.robots.emulation import EmulationConfig
    from robogym_ray.robots.server import LogLimit, RobotServerCore

log = logging.getLogger(__name__)

_serial = itertools.count()


class InProcessClient:
    """``RobotServerClient``'s four calls on a core in this process (see the module docstring).

    Args:
        core: the robot core (owned by the lease, not by the client).
        address: a name for messages (``inprocess:mir100#3``).
        deadlines: per-call deadlines, checked when the call returns.
        state_limit: no legitimate state value is beyond +- this.
    """

    def __init__(
        self, core: RobotServerCore, *, address: str, deadlines: Deadlines, state_limit: float
    ) -> None:
        from robogym_ray.robots.server import LogLimit  # lazy: robots import PyBullet models

        self.core = core
        self.address = address
        self.deadlines = deadlines
        self.state_limit = state_limit
        self._log_limit: LogLimit = LogLimit()

    def get_state(self) -> pb.State:
        return self._state("GetState", self.core.get_state, self.deadlines.get_state)

    def set_state(self, msg: pb.State) -> None:
        from robogym_ray.robots.server import msg_to_request

        self._call("SetState", lambda: self.core.set_state(msg_to_request(msg)),
                   self.deadlines.set_state)  # fmt: skip

    def send_action(self, action: Sequence[float] | np.ndarray) -> None:
        vec = _wire_action(action)
        self._call("SendAction", lambda: self.core.send_action(vec), self.deadlines.send_action)

    def send_action_get_state(self, action: Sequence[float] | np.ndarray) -> pb.State:
        vec = _wire_action(action)
        return self._state(
            "SendActionGetState",
            lambda: self.core.send_action_get_state(vec),
            self.deadlines.send_action_get_state,
        )

    def get_arguments(self) -> pb.Arguments:
        from robogym_ray.robots.server import arguments_to_msg

        call = self.core.get_arguments
        return arguments_to_msg(self._call("GetArguments", call, self.deadlines.get_state))

    def close(self) -> None:
        """Nothing to close: the core belongs to the lease."""

    def __repr__(self) -> str:
        return f"InProcessClient({self.address!r})"

    # -- internals -------------------------------------------------------------------------
    def _state(self, rpc: str, call: Callable[[], Any], deadline: float) -> pb.State:
        from robogym_ray.robots.server import snapshot_to_msg

        snapshot = self._call(rpc, call, deadline)
        state = np.asarray(snapshot.state, dtype=np.float64)
        values = np.fromiter(snapshot.state_dict.values(), float, len(snapshot.state_dict))
        msg = snapshot_to_msg(snapshot)
        # One vectorised look on the hot path; the per-value wording only when something is off.
        if not (_within(state, self.state_limit) and _within(values, self.state_limit)):
            problem = check_state(msg, self.state_limit) or "state is not valid"
            raise RobotServerError(f"{rpc}: {problem}", address=self.address,
                                   cause="invalid_state")  # fmt: skip
        return msg

    def _call(self, rpc: str, call: Callable[[], Any], deadline: float) -> Any:
        from robogym_ray.robots.server import ascii_safe, reject

        start = time.perf_counter()
        try:
            result = call()
        except Exception as exc:  # noqa: BLE001 - the servicer's convention: a refusal
            message = ascii_safe(reject(self.core, self._log_limit, rpc, exc))
            raise RobotServerError(
                f"{rpc} rejected (success=false): {message}", address=self.address, cause="rejected"
            ) from None
        if time.perf_counter() - start > deadline:
            raise deadline_error(rpc, deadline, self.address)
        return result


def _wire_action(action: Sequence[float] | np.ndarray) -> np.ndarray:
    """The action as the wire carries it: checked, then float32 (the core makes it float64)."""
    return check_action(action).astype(np.float32)


def _within(values: np.ndarray, limit: float) -> bool:
    return bool(np.isfinite(values).all()) and (values.size == 0 or np.abs(values).max() <= limit)


@dataclass
class InProcessLease:
    """One in-process robot core, from ``acquire`` to ``release`` (``ServerLease`` protocol)."""

    core: RobotServerCore
    address: str
    provider: InProcessServerProvider
    token: str | None = None
    released: bool = False

    def connect(self, deadlines: Deadlines) -> InProcessClient:
        """The client an env talks to (instead of a gRPC client to ``address``)."""
        return InProcessClient(self.core, address=self.address, deadlines=deadlines,
                               state_limit=self.provider.state_limit)  # fmt: skip

    def report_fault(self, cause: str) -> None:
        self.provider.fault(self.address, cause)

    def release(self) -> None:
        if not self.released:
            self.released = True
            self.core.close()


@dataclass
class InProcessServerProvider:
    """Builds a robot core in this process per lease (the default of every Sim env).

    Args:
        emulation: emulated real robots (noise, latency, dynamics differences) instead of the
            plain simulation.
        state_limit: a state value beyond +- this is a broken state (as the supervisor's).
        restart: backoff and give-up limit of rebuilds (the supervisor's policy); the limit
            counts the rebuilds of every core this provider built.
    """

    emulation: EmulationConfig | None = None
    state_limit: float = 1e4
    restart: RestartPolicy = field(default_factory=RestartPolicy)
    _book: RestartBook | None = field(default=None, repr=False)

    @property
    def restarts(self) -> Counter[str]:
        """Rebuilds by cause (``FaultCause`` values), over this provider's life (a copy)."""
        return Counter() if self._book is None else Counter(self._book.counts)

    def acquire(
        self, robot: str, scene: str | None, options: Mapping[str, str], seed: int | None
    ) -> InProcessLease:
        from robogym_ray.robots.registry import make_robot  # lazy: imports PyBullet
        from robogym_ray.robots.server import RobotServerCore

        if self._book is not None and self._book.given_up:
            raise RobotServerError(
                f"in-process {robot} was given up after repeated faults "
                f"(restarts by cause: {dict(self.restarts)})",
                address=f"inprocess:{robot}", cause="given_up",
            )  # fmt: skip
        sim = make_robot(robot, scene=scene, seed=seed, options=options)
        if self.emulation is not None:
            from robogym_ray.robots.emulation import emulate

            sim = emulate(sim, self.emulation, seed=seed)
        return InProcessLease(RobotServerCore(sim), f"inprocess:{robot}#{next(_serial)}", self)

    def fault(self, address: str, cause: str) -> None:
        """Count a fault of the core at ``address``; wait out the policy's backoff, or raise
        ``RobotServerError(cause="given_up")`` past its limit."""
        if self._book is None:
            self._book = RestartBook(self.restart, "in-process simulation")
        decision = self._book.record(cause, time.monotonic())
        if not decision.restart:
            raise RobotServerError(decision.message, address=address, cause="given_up")
        log.warning("in-process simulation %s faulted (%s); rebuilt", address, cause)
        if decision.delay_s > 0:  # restart backoff, not simulated time
            time.sleep(decision.delay_s)
