"""A sweep's settings: the base config with ``--set KEY=VALUE`` on top and the search space of
``--space KEY=SPEC``, read and checked without Ray.

A key is a config field, dotted by its section (``d4pg.sigma``, ``train.workers``,
``emulation.laser_noise_sigma``); a bare field name is the ``train`` section's. A value is
JSON where it parses (``0.2``, ``true``, ``[256, 256]``, ``"text"``), else the text itself.

Specs: ``0.1,0.2,0.3`` or a JSON list (``[[256,256],[400,300]]``) is a grid (every value, in
every trial combination); ``uniform(A,B)``, ``loguniform(A,B)``, ``randint(A,B)`` (B excluded)
and ``choice(X,Y,...)`` are drawn anew for each trial (``--samples`` of them).
"""

from __future__ import annotations

import dataclasses
import itertools
import json
import re
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from robogym_ray.config import quote
from robogym_ray.errors import ConfigError
from robogym_ray.text import did_you_mean
from robogym_ray.training.settings import SECTIONS

RANDOM = ("uniform", "loguniform", "randint", "choice")
"""Specs drawn per trial; the others are grids."""


@dataclass(frozen=True)
class Axis:
    """One searched key: a grid of values, or a distribution Tune draws from."""

    section: str
    field: str
    kind: str
    """``grid`` or one of ``RANDOM``."""
    values: tuple[Any, ...]
    """The grid's values, a distribution's bounds, or ``choice``'s options."""

    @property
    def key(self) -> str:
        return f"{self.section}.{self.field}"

    @property
    def spec(self) -> str:
        """``KEY=SPEC`` as ``--space`` takes it: a grid as a JSON list, a distribution as its
        call (a sweep's record and ``summary.md`` show the space so)."""
        if self.kind == "grid":
            return f"{self.key}={json.dumps(list(self.values))}"
        return f"{self.key}={self.kind}({', '.join(json.dumps(v) for v in self.values)})"

    def corners(self) -> tuple[Any, ...]:
        """Values that bound what a trial can get (every grid value and choice, a range's two
        ends), so checking them checks the space."""
        if self.kind == "randint":
            return (self.values[0], self.values[1] - 1)
        return self.values

    def tune_domain(self) -> Any:
        from ray import tune

        if self.kind == "grid":
            return tune.grid_search(list(self.values))
        if self.kind == "choice":
            return tune.choice(list(self.values))
        return getattr(tune, self.kind)(*self.values)


def split_key(key: str, what: str) -> tuple[str, str]:
    """``(section, field)`` of a dotted key, checked against the config classes."""
    section, _, name = key.rpartition(".")
    section = section or "train"
    if section not in SECTIONS:
        raise ConfigError(
            f"{what} {quote(key)}: no section {quote(section)}{did_you_mean(section, SECTIONS)}; "
            f"keys are {', '.join(s + '.FIELD' for s in SECTIONS)}"
        )
    known = [f.name for f in dataclasses.fields(SECTIONS[section])]
    if name not in known:
        raise ConfigError(
            f"{what} {quote(key)}: {SECTIONS[section].__name__} has no field "
            f"{quote(name)}{did_you_mean(name, known)}"
        )
    return section, name


def parse_value(text: str) -> Any:
    try:
        return json.loads(text)
    except ValueError:
        return text


def _pair(item: str, what: str) -> tuple[str, str]:
    key, eq, spec = item.partition("=")
    if not eq or not key.strip() or not spec.strip():
        raise ConfigError(f"{what} {quote(item)}: expected KEY=VALUE, e.g. d4pg.sigma=0.2")
    return key.strip(), spec.strip()


def parse_set(items: Sequence[str]) -> dict[str, dict[str, Any]]:
    """``--set KEY=VALUE`` items as sections of fixed values."""
    out: dict[str, dict[str, Any]] = {}
    for item in items:
        key, text = _pair(item, "--set")
        section, name = split_key(key, "--set")
        out.setdefault(section, {})[name] = parse_value(text)
    return out


_CALL = re.compile(r"^(\w+)\((.*)\)$", re.DOTALL)


def parse_axis(item: str) -> Axis:
    """One ``--space KEY=SPEC`` item (module docstring)."""
    key, spec = _pair(item, "--space")
    section, name = split_key(key, "--space")
    call = _CALL.match(spec)
    where = f"--space {quote(item)}"
    if call and call.group(1) not in RANDOM:
        raise ConfigError(
            f"{where}: no spec {quote(call.group(1))}"
            f"{did_you_mean(call.group(1), RANDOM)}; expected a grid "
            f"(A,B,... or a JSON list) or one of {', '.join(RANDOM)}"
        )
    if call:
        kind = call.group(1)
        args = tuple(parse_value(a.strip()) for a in _split_args(call.group(2)))
    else:
        kind = "grid"
        parsed = parse_value(spec) if spec.startswith("[") else None
        args = (
            tuple(parsed)
            if isinstance(parsed, list)
            else tuple(parse_value(a.strip()) for a in spec.split(","))
        )
    _check_args(where, kind, args)
    return Axis(section, name, kind, args)


def _split_args(text: str) -> list[str]:
    """Comma-separated arguments, commas inside brackets or quotes kept (``choice([1,2],[3])``)."""
    out, depth, quoted, start = [], 0, False, 0
    for i, ch in enumerate(text):
        if ch == '"':
            quoted = not quoted
        elif not quoted and ch in "[{":
            depth += 1
        elif not quoted and ch in "]}":
            depth -= 1
        elif not quoted and ch == "," and depth == 0:
            out.append(text[start:i])
            start = i + 1
    return [*out, text[start:]] if text.strip() else out


def _check_args(where: str, kind: str, args: tuple[Any, ...]) -> None:
    if kind in ("grid", "choice"):
        if not args or any(a == "" for a in args):
            raise ConfigError(f"{where}: expected at least one value, none empty")
        return
    if len(args) != 2 or not all(
        isinstance(a, (int, float)) and not isinstance(a, bool) for a in args
    ):
        raise ConfigError(f"{where}: {kind} takes two numbers (LOW,HIGH)")
    low, high = args
    if not low < high:
        raise ConfigError(f"{where}: expected LOW < HIGH, got {low} and {high}")
    if kind == "loguniform" and low <= 0:
        raise ConfigError(f"{where}: loguniform needs LOW > 0, got {low}")
    if kind == "randint" and not (isinstance(low, int) and isinstance(high, int)):
        raise ConfigError(f"{where}: randint takes two integers (HIGH excluded)")


def parse_space(items: Sequence[str], seeds: Sequence[int]) -> list[Axis]:
    """The search space: each ``--space`` item, and ``--seeds`` as a grid over ``train.seed``."""
    axes = [parse_axis(item) for item in items]
    keys = [a.key for a in axes]
    twice = sorted({k for k in keys if keys.count(k) > 1})
    if twice:
        raise ConfigError(f"--space: {', '.join(twice)} given twice; give each key once")
    if seeds:
        if "train.seed" in keys:
            raise ConfigError("--seeds and --space train.seed=...: give the seeds once")
        axes.append(Axis("train", "seed", "grid", tuple(seeds)))
    return axes


def with_values(
    base: Mapping[str, Mapping[str, Any]], values: Mapping[tuple[str, str], Any]
) -> dict[str, dict[str, Any]]:
    """``base``'s sections with ``{(section, field): value}`` set."""
    out = {name: dict(base.get(name, {})) for name in SECTIONS}
    for (section, name), value in values.items():
        out[section][name] = value
    return out


def corner_points(axes: Sequence[Axis]) -> Iterator[dict[tuple[str, str], Any]]:
    """Every combination of the axes' corners: the trials a grid makes, and the bounds of the
    drawn ones (each value a trial can get is between two checked ones)."""
    for combo in itertools.product(*(a.corners() for a in axes)):
        yield {(a.section, a.field): v for a, v in zip(axes, combo, strict=True)}


def param_space(
    base: Mapping[str, Mapping[str, Any]], axes: Sequence[Axis], meta: Mapping[str, Any]
) -> dict[str, Any]:
    """Tune's ``param_space``: the sections with each axis's domain in its place, and the
    sweep's own settings for the trials under ``sweep``."""
    space: dict[str, Any] = {name: dict(base.get(name, {})) for name in SECTIONS}
    for axis in axes:
        space[axis.section][axis.field] = axis.tune_domain()
    return {**space, "sweep": dict(meta)}
