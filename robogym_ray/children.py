"""Child processes that end with the process that started them.

A parent stopped by SIGTERM's default action or by SIGKILL runs no ``finally`` and no fixture
teardown, so a child it would have stopped (a robot server, ``robogym-ray manager``, a
``ray start --block`` node) keeps running, holding its ports and CPUs. Linux's parent-death
signal (``prctl(PR_SET_PDEATHSIG)``), set in the child before it runs its program, has the
kernel send the child a signal when its parent goes, however it goes. SIGTERM by default: our
commands, and ``ray start --block``, stop what they started on it.

The signal is set by a few lines of Python that the child runs first and that then ``exec``
the program (same pid), not by a ``preexec_fn``: a ``preexec_fn`` makes ``subprocess`` fork
instead of vfork, and a fork runs grpcio's fork handlers, which restart its poller thread in
the child; ``close_fds`` then closes that thread's epoll descriptor before ``exec``, and the
child aborts on ``epoll_wait error: Bad file descriptor`` (grpc/grpc#43055, grpcio 1.80 and
later). Every process of ours that starts children also talks gRPC.

The signal follows the *thread* that started the child: start children from a thread that
lives as long as they should (the main thread). Elsewhere than Linux this does nothing.
"""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
from collections.abc import Sequence
from typing import Any

PR_SET_PDEATHSIG = 1
"""``prctl`` option from ``<linux/prctl.h>``."""

# argv: parent pid, signal, program, its arguments. If the parent went before prctl took effect
# the child is now some other process's, and signals itself at once. Python ignores SIGPIPE and
# SIGXFSZ at start and exec keeps what is ignored: the program gets them back at their default,
# as subprocess's restore_signals gives them.
_ARM_AND_EXEC = (
    "import ctypes, os, signal, sys\n"
    "for name in ('SIGPIPE', 'SIGXFSZ'):\n"
    "    signal.signal(getattr(signal, name), signal.SIG_DFL)\n"
    "parent, sig = int(sys.argv[1]), int(sys.argv[2])\n"
    f"ctypes.CDLL(None, use_errno=True).prctl({PR_SET_PDEATHSIG}, sig, 0, 0, 0)\n"
    "if os.getppid() != parent:\n"
    "    os.kill(os.getpid(), sig)\n"
    "os.execv(sys.argv[3], sys.argv[4:])\n"
)


def _armed(args: Sequence[Any], sig: int, kwargs: dict[str, Any]) -> list[str]:
    """``args`` behind the arming lines. The program is looked up here, on the child's PATH or
    in its ``cwd``, so that a missing one raises FileNotFoundError in the parent, as
    ``subprocess`` does."""
    if isinstance(args, (str, bytes)) or not args or kwargs.get("shell") or "executable" in kwargs:
        raise TypeError(f"children take an argument list, no shell or executable: {args!r}")
    argv = [os.fsdecode(a) for a in args]
    if os.sep in argv[0]:
        program: str | None = argv[0]
        found = os.path.join(os.fsdecode(kwargs.get("cwd") or "."), argv[0])
    else:
        path = os.pathsep.join(os.get_exec_path(kwargs.get("env")))
        program = found = shutil.which(argv[0], path=path)
    if program is None or found is None or not os.access(found, os.X_OK):
        raise FileNotFoundError(f"no program {argv[0]!r} on the child's PATH or in its cwd")
    # -I -S: no site, no PYTHON* variables; the program gets the environment unchanged.
    return [sys.executable, "-I", "-S", "-c", _ARM_AND_EXEC, str(os.getpid()), str(sig),
            program, *argv]  # fmt: skip


def _linux() -> bool:
    return sys.platform.startswith("linux")


def popen(args: Any, *, death_signal: int = signal.SIGTERM, **kwargs: Any) -> subprocess.Popen:
    """``subprocess.Popen(args, **kwargs)`` (an argument list) whose child ends with this
    process: it gets ``death_signal`` when the calling thread's process ends."""
    if _linux():
        args = _armed(args, int(death_signal), kwargs)
    return subprocess.Popen(args, **kwargs)


def run(
    args: Any, *, death_signal: int = signal.SIGTERM, **kwargs: Any
) -> subprocess.CompletedProcess:
    """``subprocess.run(args, **kwargs)`` (an argument list) whose child ends with this process
    (as ``popen``)."""
    if _linux():
        args = _armed(args, int(death_signal), kwargs)
    return subprocess.run(args, **kwargs)
