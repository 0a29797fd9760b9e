"""The foreground commands' way to stop (``serve``, ``manager``): SIGINT (Ctrl-C) or SIGTERM
(a supervisor's restart, ``kill``, a batch system) ends them, always.

Two things could keep such a stop from ending the process, and both are closed here:

- A signal is handled in the main thread, between bytecodes. The main thread waits in short
  timed waits rather than one unbounded one, so the handler runs within half a second however
  the wait is woken.
- Once the stop is asked, a deadline is armed: should any part of the shutdown hang (gRPC's,
  the robot's, the interpreter's own exit), every thread's stack is written to stderr and the
  process exits with status 1. A hung stop is then a failure that says where it hung, not a
  process that holds its port (and a supervisor's keep-port restart) forever.
"""

from __future__ import annotations

import faulthandler
import signal
import threading

STOP_DEADLINE_S = 20.0
"""Seconds a foreground command may take to stop once asked, before its stacks are dumped."""


class StopSignals:
    """SIGINT and SIGTERM, caught from construction on (install it before telling anyone the
    process is listening: a signal that comes first must not kill it half-started)."""

    def __init__(self) -> None:
        self._asked = threading.Event()
        self.signal: signal.Signals | None = None
        for sig in (signal.SIGINT, signal.SIGTERM):
            signal.signal(sig, self._handle)

    def _handle(self, signum: int, _frame: object) -> None:
        self.signal = signal.Signals(signum)
        self._asked.set()

    def wait(self, deadline_s: float = STOP_DEADLINE_S) -> signal.Signals:
        """Block until a stop signal comes; then arm the deadline of ``deadline_s`` for the
        rest of the process's life, and return the signal."""
        while not self._asked.wait(0.5):  # timed: the handler runs between two waits at worst
            pass
        faulthandler.dump_traceback_later(deadline_s, exit=True)
        assert self.signal is not None
        return self.signal
