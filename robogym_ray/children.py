"""Child processes that end with the process that started them.

A parent stopped by SIGTERM's default action or by SIGKILL runs no ``finally`` and no fixture
teardown, so a child it would have stopped (a robot server, ``robogym-ray manager``, a
``ray start --block`` node) keeps running, holding its ports and CPUs. Linux's parent-death
signal (``prctl(PR_SET_PDEATHSIG)``), set in the child before it runs its program, has the
kernel send the child a signal when its parent goes, however it goes. SIGTERM by default: our
commands, and ``ray start --block``, stop what they started on it.

The signal follows the *thread* that started the child: start children from a thread that
lives as long as they should (the main thread). Elsewhere than Linux this does nothing.
"""

from __future__ import annotations

import ctypes
import os
import signal
import subprocess
import sys
from collections.abc import Callable
from typing import Any

PR_SET_PDEATHSIG = 1
"""``prctl`` option from ``<linux/prctl.h>``."""

# Looked up here, in the parent: loading a library in a child forked from a threaded process
# can deadlock on a lock another thread held at the fork.
_PRCTL = ctypes.CDLL(None, use_errno=True).prctl if sys.platform.startswith("linux") else None


def die_with_parent(sig: int = signal.SIGTERM) -> Callable[[], None]:
    """A ``preexec_fn`` for ``subprocess``: the child gets ``sig`` when the calling thread's
    process (the parent) ends; one that ended before the child could ask gets it at once."""
    parent = os.getpid()

    def arm() -> None:  # runs in the child, between fork and exec
        if _PRCTL is None:
            return
        _PRCTL(PR_SET_PDEATHSIG, int(sig), 0, 0, 0)
        if os.getppid() != parent:  # the parent went before the line above took effect
            os.kill(os.getpid(), sig)

    return arm


def popen(args: Any, *, death_signal: int = signal.SIGTERM, **kwargs: Any) -> subprocess.Popen:
    """``subprocess.Popen(args, **kwargs)`` whose child ends with this process
    (``die_with_parent``)."""
    return subprocess.Popen(args, preexec_fn=die_with_parent(death_signal), **kwargs)


def run(
    args: Any, *, death_signal: int = signal.SIGTERM, **kwargs: Any
) -> subprocess.CompletedProcess:
    """``subprocess.run(args, **kwargs)`` whose child ends with this process
    (``die_with_parent``)."""
    return subprocess.run(args, preexec_fn=die_with_parent(death_signal), **kwargs)
