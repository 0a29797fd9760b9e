"""Typed errors shared by the robot side, the client side and the training program.

Every message names what was wrong, the offending value and what was expected, so a user
reading a traceback from a rollout worker on another node can act without a debugger.
"""

from __future__ import annotations


class RoboGymRayError(Exception):
    """Base class of every error this package raises on purpose."""


class ConfigError(RoboGymRayError, ValueError):
    """A configuration value (CLI flag, config file, launch argument) is malformed."""


class FieldError(ConfigError):
    """A config field's value out of its range (``config.check_ranges``). Its parts let a
    command line name the flag the value came from instead of the field
    (``config.merge_config``); ``__init__`` takes the message alone, as Ray's pickling wants.

    Attributes:
        field: the config field, e.g. ``workers``.
        shown: its value, quoted for one line.
        expected: what it should have been, e.g. ``>= 1``.
    """

    def __init__(self, message: str, *, field: str = "", shown: str = "", expected: str = ""):
        super().__init__(message)
        self.field, self.shown, self.expected = field, shown, expected


class UnknownRobotError(ConfigError):
    """A robot, scene, task or mode name that no registry knows."""


class InvalidActionError(RoboGymRayError, ValueError):
    """An action of the wrong length, with NaN/inf, or outside the accepted range."""


class InvalidStateError(RoboGymRayError, ValueError):
    """A state (sent to SetState or received from a server) that is malformed or out of bounds."""


class RobotServerError(RoboGymRayError):
    """A robot server could not be reached, timed out, or answered ``success=false``.

    Attributes:
        address: ``host:port`` of the server, when known.
        cause: a short machine-readable cause (``connection``, ``deadline``, ``rejected`` ...).
    """

    def __init__(self, message: str, *, address: str = "", cause: str = "error") -> None:
        super().__init__(f"{message} (server {address})" if address else message)
        self.address = address
        self.cause = cause


class RobotFaultError(RoboGymRayError):
    """The robot hardware stopped on an error (a reflex, a lost connection, a refused motion):
    the arm is stopped and refuses commands until an operator recovers it."""


class RayNotFoundError(RoboGymRayError, ConnectionError):
    """No Ray runs at the address a command was told to join (``auto``: none on this machine);
    raised before ``ray.init``, which would print a traceback or wait for the address."""


class RenderError(RoboGymRayError, RuntimeError):
    """A render mode cannot work here (no display for ``human``, a missing optional package)."""


class RunStoppedError(RoboGymRayError):
    """Something ended a training run before its end: a file it could not write
    (``DiskWriteError``), a learner that restarted with nothing to restore
    (``LearnerLostError``). ``also`` adds what the run kept, for the one ``error:`` line."""

    def also(self, note: str) -> RunStoppedError:
        """The same error (type and attributes) with ``note`` appended to its message."""
        copy = type(self).__new__(type(self))
        copy.__dict__.update(self.__dict__)
        copy.args = (f"{self}; {note}",)
        return copy


class LearnerLostError(RunStoppedError):
    """The learner's process died (e.g. with its node) and the one Ray started in its place
    found no checkpoint in the run's storage: what it had learned is gone, so the run stops
    rather than train on from scratch as if nothing had happened."""


class DiskWriteError(RunStoppedError):
    """A file of a run (checkpoint, replay, summary, TensorBoard events) could not be written;
    the file that was there before is untouched and no temporary file is left behind.

    Raised inside the learner actor too: Ray pickles it with ``args`` (the message) and
    ``__dict__`` (the attributes), so ``__init__`` takes the message alone.

    Attributes:
        path: the file that could not be written (its real name, not a temporary one).
        reason: why, e.g. ``no space left on device`` (``DiskFullError``).
        what: what the file is (``learner checkpoint``, ``summary`` ...).
    """

    def __init__(self, message: str, *, path: str = "", reason: str = "", what: str = "") -> None:
        super().__init__(message)
        self.path, self.reason, self.what = path, reason, what

    @classmethod
    def of(cls, what: str, path: object, exc: OSError) -> DiskWriteError:
        """The error for ``exc`` while writing ``what`` to ``path``; ENOSPC and EDQUOT (the disk
        or the quota full) give a ``DiskFullError``."""
        import errno
        import os

        reason = os.strerror(exc.errno) if exc.errno else str(exc)
        reason = reason[:1].lower() + reason[1:]  # strerror: "No space left on device"
        kind = DiskFullError if exc.errno in (errno.ENOSPC, errno.EDQUOT) else DiskWriteError
        message = f"cannot write {what} {path}: {reason}"
        return kind(message, path=str(path), reason=reason, what=what)


class DiskFullError(DiskWriteError):
    """A ``DiskWriteError`` because the disk (or the user's quota) is full."""


class BindError(RoboGymRayError, OSError):
    """A server cannot listen on its address (not an interface of this machine, no permission).

    An ``OSError`` as well, so callers that fall back to another port on a failed bind (the
    supervisor's keep-port restart) keep doing so.
    """

    def __init__(self, message: str, *, host: str = "", port: int = 0) -> None:
        super().__init__(message)
        self.host = host
        self.port = port


class PortInUseError(BindError):
    """A server's TCP port is held already: by another server of ours or any other program.

    Servers bind exclusively (no SO_REUSEPORT); sharing a port would let the kernel spread new
    clients of one address over two robots.
    """
