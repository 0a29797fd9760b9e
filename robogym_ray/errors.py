"""Typed errors shared by the robot side, the client side and the training program.

Every message names what was wrong, the offending value and what was expected, so a user
reading a traceback from a rollout worker on another node can act without a debugger.
"""

from __future__ import annotations


class RoboGymRayError(Exception):
    """Base class of every error this package raises on purpose."""


class ConfigError(RoboGymRayError, ValueError):
    """A configuration value (CLI flag, config file, launch argument) is malformed."""


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


class RenderError(RoboGymRayError, RuntimeError):
    """A render mode cannot work here (no display for ``human``, a missing optional package)."""
