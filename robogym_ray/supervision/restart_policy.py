"""When to restart a robot server, how long to wait first, and when to give it up.

Plain Python, no Ray: the supervisor owns one ``RestartBook`` per server and asks it what to do
each time a fault is seen. The five fault causes are the paper's; a client's reported cause
(``RobotServerError.cause``, see ``robogym_ray.protocol.client``) maps onto them with
``FaultCause.parse``.
"""

from __future__ import annotations

import enum
from collections import Counter, deque
from dataclasses import dataclass


class FaultCause(str, enum.Enum):
    """Why a robot server is restarted."""

    CONNECTION = "connection"
    """The server cannot be reached (refused, reset: its process is gone)."""
    DEADLINE = "deadline"
    """A client's call got no answer within its deadline."""
    HUNG = "hung"
    """The supervisor's health probe (GetState, short deadline) got no answer."""
    INVALID_STATE = "invalid_state"
    """The state holds NaN/inf or values beyond the supervisor's limit."""
    MANUAL = "manual"
    """Somebody asked for a restart."""
    OTHER = "other"
    """A client reported a cause we do not know; restarted like a connection fault."""

    @classmethod
    def parse(cls, text: str | FaultCause) -> FaultCause:
        """Map a reported cause (``"deadline"``, ``"nan"``, ``"hang"`` ...) to a FaultCause."""
        if isinstance(text, FaultCause):
            return text
        return _ALIASES.get(str(text).strip().lower(), cls.OTHER)


_ALIASES: dict[str, FaultCause] = {
    **{c.value: c for c in FaultCause},
    "unavailable": FaultCause.CONNECTION,
    "timeout": FaultCause.DEADLINE,
    "deadline_exceeded": FaultCause.DEADLINE,
    "hang": FaultCause.HUNG,
    "probe_timeout": FaultCause.HUNG,
    "nan": FaultCause.INVALID_STATE,
    "state": FaultCause.INVALID_STATE,
    "out_of_bounds": FaultCause.INVALID_STATE,
    "restart": FaultCause.MANUAL,
}


@dataclass(frozen=True)
class RestartPolicy:
    """How a supervisor restarts one robot server."""

    max_restarts: int = 5
    """Automatic restarts allowed within ``window_s``; one more fault gives the server up."""
    window_s: float = 300.0
    """Seconds over which restarts are counted against ``max_restarts`` (a server that faults
    once an hour is kept; one that faults on every start is not)."""
    backoff_s: float = 0.5
    """Wait before the second restart within the window; the first restart is immediate."""
    backoff_factor: float = 2.0
    """Each further restart within the window waits this much longer."""
    backoff_max_s: float = 30.0
    """Upper bound of the wait."""

    def __post_init__(self) -> None:
        if self.max_restarts < 0 or self.window_s <= 0 or self.backoff_factor < 1:
            raise ValueError(
                f"invalid RestartPolicy: max_restarts={self.max_restarts} (>= 0), "
                f"window_s={self.window_s} (> 0), backoff_factor={self.backoff_factor} (>= 1)"
            )


@dataclass(frozen=True)
class Decision:
    """What to do about one fault."""

    restart: bool
    """False: the server is given up (``message`` says why)."""
    delay_s: float
    """Seconds to wait before restarting."""
    message: str


class RestartBook:
    """Restart counts per cause and the recent-restart window of one server.

    Manual restarts are counted but never count against the limit: an operator asked for them.
    """

    def __init__(self, policy: RestartPolicy, name: str = "server") -> None:
        self.policy = policy
        self.name = name
        self.counts: Counter[str] = Counter()
        self.given_up = False
        self._recent: deque[float] = deque()  # times of automatic restarts within the window

    def record(self, cause: FaultCause | str, now: float) -> Decision:
        """Count a fault seen at ``now`` (monotonic seconds) and decide what to do about it."""
        cause = FaultCause.parse(cause)
        if self.given_up:
            return Decision(False, 0.0, f"{self.name} was already given up")
        if cause is FaultCause.MANUAL:
            self.counts[cause.value] += 1
            return Decision(True, 0.0, f"{self.name}: manual restart")
        while self._recent and now - self._recent[0] > self.policy.window_s:
            self._recent.popleft()
        if len(self._recent) >= self.policy.max_restarts:
            self.given_up = True
            return Decision(
                False,
                0.0,
                f"{self.name} given up after {len(self._recent)} restarts within "
                f"{self.policy.window_s:g} s (limit {self.policy.max_restarts}); last fault: "
                f"{cause.value}; restarts by cause: {dict(self.counts)}",
            )
        delay = self._delay(len(self._recent))
        self._recent.append(now)
        self.counts[cause.value] += 1
        return Decision(True, delay, f"{self.name}: restart #{len(self._recent)} ({cause.value})")

    def _delay(self, previous: int) -> float:
        if previous == 0:
            return 0.0
        p = self.policy
        return min(p.backoff_max_s, p.backoff_s * p.backoff_factor ** (previous - 1))
