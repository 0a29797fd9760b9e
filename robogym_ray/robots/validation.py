"""Checks and previews for values that come from a client (SetState, launch options).

Robot servers face any client on the network, so what a client sends must neither be applied
out of a physically sensible range (a yaw of 3.4e38, an object 3e38 m away, a trajectory one
period of which needs gigabytes) nor be copied in full into a reply or a log line (a 60 MB key
list would become 60 MB of log). Robots check with ``check_range`` and quote client text with
``robogym_ray.text``'s ``quote`` / ``preview``; the server cuts every message with its
``clip_text``. One place, one shape.
"""

from __future__ import annotations

import math
from collections.abc import Collection, Iterable, Mapping

from robogym_ray.errors import ConfigError, InvalidStateError, RoboGymRayError, UnknownRobotError
from robogym_ray.text import did_you_mean, quote


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


def parse_option_number(name: str, text: str) -> float:
    """A launch option's value as a finite float; ConfigError naming the option otherwise."""
    try:
        value = float(text)
    except ValueError:
        raise ConfigError(f"option {name}={quote(text)} is not a number") from None
    if not math.isfinite(value):
        raise ConfigError(f"option {name}={quote(text)} must be finite")
    return value


def parse_cycle_option(name: str, text: str, rates: tuple[float, float]) -> float:
    """A launch option that gives a rate (Hz) as the cycle it means (s): ``1 / rate``, the rate
    finite and within ``rates`` (a rate of 1e-3 Hz would make one action simulate 1,000 s)."""
    rate = parse_option_number(name, text)
    low, high = rates
    return 1.0 / check_range(f"option {name}", rate, low, high, "Hz", ConfigError)


def parse_option_bool(name: str, text: str) -> bool:
    """A launch option's value as roslaunch reads a boolean (``true``/``1``, ``false``/``0``)."""
    lowered = text.strip().lower()
    if lowered in ("true", "1"):
        return True
    if lowered in ("false", "0"):
        return False
    raise ConfigError(f"option {name}={quote(text)} is not a boolean (true/false)")


def check_option_names(robot: str, names: Iterable[str], known: Collection[str]) -> None:
    """ConfigError for the first of ``names`` that ``robot``'s launch file does not know: a typo
    must not silently become a default."""
    for name in names:
        if name not in known:
            listed = ", ".join(sorted(known))
            hint = did_you_mean(name, known)
            raise ConfigError(f"unknown {robot} option {quote(name)}{hint}; known: {listed}")


def resolve_scene(
    robot: str,
    scene: str | None,
    world_name: str | None,
    scenes: Collection[str],
    worlds: Mapping[str, str],
    default: str,
) -> str:
    """The scene named by an explicit ``scene`` (a scene or a world file) and/or the launch
    option ``world_name``, which must agree; ``default`` when neither is given.

    Raises:
        UnknownRobotError: a name that is neither a scene nor a known world file.
        ConfigError: ``scene`` and ``world_name`` name different scenes.
    """
    resolved = []
    for name in (n for n in (scene, world_name) if n is not None):
        key = worlds.get(name, name)
        if key not in scenes:
            names = [*sorted(scenes), *sorted(worlds)]
            hint = did_you_mean(name, names)
            raise UnknownRobotError(
                f"unknown {robot} scene/world {quote(name)}{hint}; known: {', '.join(names)}"
            )
        resolved.append(key)
    if len(set(resolved)) > 1:
        raise ConfigError(f"scene {scene!r} contradicts option world_name={world_name!r}")
    return resolved[0] if resolved else default


def _number(value: float) -> str:
    text = repr(value)
    # A float32 from the wire: 3e38 arrives as 2.9999999521443642e+38; 7 digits is all it holds.
    return text if len(text) <= 12 else f"{value:.7g}"
