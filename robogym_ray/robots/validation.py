"""Checks for values that come from a client (SetState, launch options).

Robot servers face any client on the network, so what a client sends must not be applied out of a
physically sensible range (a yaw of 3.4e38, an object 3e38 m away, a trajectory one period of which
needs gigabytes). Every robot checks with ``check_range``, so the messages look alike: the field,
the value and the allowed range.
"""

from __future__ import annotations

import math

from robogym_ray.errors import InvalidStateError, RoboGymRayError


def check_range(
    what: str,
    value: float,
    low: float,
    high: float,
    unit: str = "",
    error: type[RoboGymRayError] = InvalidStateError,
) -> float:
    """Return ``value`` as a float if it is finite and within ``[low, high]``, else raise.

    Args:
        what: the field as the client knows it (``state[2] (target yaw)``, ``object_0_x``).
        unit: appended to the range in the message (``m``, ``rad``, ``Hz``).
        error: the error type to raise (InvalidStateError for SetState, ConfigError for options).
    """
    number = float(value)
    if math.isfinite(number) and low <= number <= high:
        return number
    problem = "" if math.isfinite(number) else " (non-finite)"
    suffix = f" {unit}" if unit else ""
    raise error(f"{what} = {_number(number)}{problem}; expected within [{low:g}, {high:g}]{suffix}")


def _number(value: float) -> str:
    text = repr(value)
    # A float32 from the wire: 3e38 arrives as 2.9999999521443642e+38; 7 digits is all it holds.
    return text if len(text) <= 12 else f"{value:.7g}"
