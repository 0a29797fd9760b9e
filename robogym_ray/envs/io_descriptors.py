"""Isaac Lab's ``IO_descriptors.yaml``: what a policy observes and commands, checked against an
env before the robot moves, and the action term applied as the file declares it.

Isaac Lab 3 writes the file beside ``exported/policy.pt`` (``isaaclab/envs/utils/
io_descriptors.py``; examples in its ``docs/source/_static/policy_deployment/
01_io_descriptors/``). Its keys (``yaml.safe_dump``, sorted):

* ``observations.policy`` - the policy group's terms in order, each with ``name`` (the term's
  function: ``joint_pos``, ``generated_commands`` ...), ``shape``, ``dtype``, ``joint_names``
  (joint terms), ``joint_pos_offsets`` (``joint_pos_rel``) and ``overloads`` (``scale``,
  ``clip``, ``history_length``, ``flatten_history_dim``);
* ``actions`` - the action terms, each with ``full_path`` (its class), ``action_type``,
  ``joint_names``, ``scale``, ``offset``, ``clip`` (``[low, high]`` per joint, or null) and
  ``shape``;
* ``articulations.<name>`` - ``joint_names`` and ``default_joint_pos`` (and gains, unused here);
* ``scene`` - ``dt`` (the policy's period, s), ``decimation`` and ``physics_dt``.

An env that runs Isaac Lab policies says what it expects as an ``IOContract``
(``env.isaac_io()``); ``check`` compares the two and refuses the first difference in one line
that names the term and both values. What can be checked is listed in ``OBSERVATION_TERMS`` and
``ACTION_TERMS`` (docs/isaac-lab.md); any other term is refused by name.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from robogym_ray.config import quote
from robogym_ray.errors import ConfigError

OBSERVATION_TERMS = (
    "joint_pos",
    "joint_pos_rel",
    "joint_vel",
    "joint_vel_rel",
    "generated_commands",
    "last_action",
)
"""Observation terms (Isaac Lab's function names) an env can declare and a file may list."""
ACTION_TERMS = ("JointPositionAction", "RelativeJointPositionAction")
"""Action term classes (the last part of ``full_path``) an env can declare and a file may use."""
TOLERANCE = 1e-4
"""Numbers (scale, offset, default pose, dt) agree within this; the YAML carries float32s."""


@dataclass(frozen=True)
class ObsTerm:
    """One observation term as an env observes it."""

    name: str
    size: int
    joint_names: tuple[str, ...] | None = None
    """Joint terms: the joints, in the observation's order."""
    offsets: tuple[float, ...] | None = None
    """``joint_pos_rel``: the positions subtracted (the default pose)."""


@dataclass(frozen=True)
class ActionTermSpec:
    """The env's action: ``target = base + scale * action + offset`` per joint, where ``base`` is
    the measured joints for ``RelativeJointPositionAction`` and 0 for ``JointPositionAction``."""

    kind: str
    joint_names: tuple[str, ...]
    scale: float
    offset: tuple[float, ...]


@dataclass(frozen=True)
class IOContract:
    """What an env expects of an Isaac Lab policy (``env.isaac_io()``)."""

    observations: tuple[ObsTerm, ...]
    action: ActionTermSpec
    joint_names: tuple[str, ...]
    default_joint_pos: tuple[float, ...]
    dt: float
    """Seconds between actions."""


@dataclass(frozen=True)
class ActionMap:
    """The file's action term: ``clip(scale * raw + offset)``, per joint."""

    scale: np.ndarray
    offset: np.ndarray
    clip: np.ndarray | None
    """``(n, 2)`` bounds of the processed action, or None."""

    def processed(self, raw: np.ndarray) -> np.ndarray:
        out = self.scale * np.asarray(raw, dtype=np.float64) + self.offset
        return out if self.clip is None else np.clip(out, self.clip[:, 0], self.clip[:, 1])


@dataclass(frozen=True)
class IODescriptors:
    """A parsed ``IO_descriptors.yaml``: the raw mapping plus its path for messages."""

    path: Path
    data: Mapping[str, Any]

    @property
    def observations(self) -> list[Mapping[str, Any]]:
        return self.data["observations"]["policy"]

    @property
    def actions(self) -> list[Mapping[str, Any]]:
        return self.data["actions"]

    @property
    def obs_size(self) -> int:
        return sum(_size(t) for t in self.observations)


def load(path: str | Path) -> IODescriptors:
    """Read and shape-check ``path`` (keys present and of the right kind), nothing more.

    Raises:
        ConfigError: no such file, not YAML, or a key missing or of the wrong kind.
    """
    import yaml

    where = Path(path)
    if not where.is_file():
        raise ConfigError(
            f"{where}: no such file (--io-descriptors: Isaac Lab's IO_descriptors.yaml)"
        )
    try:
        data = yaml.safe_load(where.read_text())
    except (yaml.YAMLError, UnicodeDecodeError) as exc:
        first = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise ConfigError(f"{where}: not YAML ({first})") from None
    for key, kind in (
        ("observations", dict),
        ("actions", list),
        ("articulations", dict),
        ("scene", dict),
    ):
        if not isinstance(data, dict) or not isinstance(data.get(key), kind):
            raise ConfigError(f"{where}: no {key!r} {kind.__name__} - not an IO_descriptors.yaml")
    if not isinstance(data["observations"].get("policy"), list):
        raise ConfigError(f"{where}: no 'observations.policy' list of terms")
    return IODescriptors(where, data)


def check(io: IODescriptors, contract: IOContract, env_id: str) -> ActionMap:
    """Compare ``io`` with what ``env_id`` expects; the action map the runner applies.

    Raises:
        ConfigError: the first difference, in one line naming the term and both values.
    """
    for i, term in enumerate(io.observations):
        _check_obs_term(io, i, term, contract, env_id)
    if len(io.observations) != len(contract.observations):
        names = [t.name for t in contract.observations]
        raise ConfigError(
            f"{io.path}: {len(io.observations)} observation terms; {env_id} "
            f"observes {len(names)}: {names}"
        )
    _check_articulation(io, contract, env_id)
    dt = _number(io, io.data["scene"], "dt", "scene")
    if abs(dt - contract.dt) > TOLERANCE * contract.dt:
        raise ConfigError(
            f"{io.path}: scene dt {dt:.6g} s (a policy at {1 / dt:.4g} Hz); "
            f"{env_id} acts every {contract.dt:.6g} s ({1 / contract.dt:.4g} Hz)"
        )
    if len(io.actions) != 1:
        raise ConfigError(
            f"{io.path}: {len(io.actions)} action terms; {env_id} has one ({contract.action.kind})"
        )
    return _check_action(io, io.actions[0], contract.action, env_id)


def _check_obs_term(
    io: IODescriptors, i: int, term: Any, contract: IOContract, env_id: str
) -> None:
    name = term.get("name") if isinstance(term, dict) else None
    if name not in OBSERVATION_TERMS:
        what = f"{quote(name)} ({term.get('full_path')})" if isinstance(term, dict) else quote(term)
        raise ConfigError(
            f"{io.path}: observation term {i} {what} is not supported; "
            f"supported: {', '.join(OBSERVATION_TERMS)}"
        )
    if i >= len(contract.observations) or contract.observations[i].name != name:
        want = contract.observations[i].name if i < len(contract.observations) else "nothing"
        raise ConfigError(
            f"{io.path}: observation term {i} is {name!r}; {env_id} observes {want!r} there"
        )
    want_term = contract.observations[i]
    if _size(term) != want_term.size:
        raise ConfigError(
            f"{io.path}: observation term {name!r} has shape {term.get('shape')}; "
            f"{env_id}'s has [{want_term.size}]"
        )
    overloads = term.get("overloads") or {}
    for key, plain in (("scale", None), ("clip", None), ("history_length", 0)):
        if overloads.get(key, plain) not in (plain, None):
            raise ConfigError(
                f"{io.path}: observation term {name!r} {key} "
                f"{quote(overloads[key])}; {env_id} observes it without one"
            )
    if want_term.joint_names is not None:
        _same_names(
            io, f"observation term {name!r}", term.get("joint_names"), want_term.joint_names, env_id
        )
    if want_term.offsets is not None:
        _same_numbers(
            io,
            f"observation term {name!r} joint_pos_offsets",
            term.get("joint_pos_offsets"),
            want_term.offsets,
            env_id,
        )


def _check_articulation(io: IODescriptors, contract: IOContract, env_id: str) -> None:
    arts = io.data["articulations"]
    if len(arts) != 1:
        raise ConfigError(
            f"{io.path}: {len(arts)} articulations {sorted(arts)}; {env_id} drives one robot"
        )
    ((name, art),) = arts.items()
    if not isinstance(art, dict):
        raise ConfigError(f"{io.path}: articulations.{name} is not a mapping")
    _same_names(io, f"articulation {name!r}", art.get("joint_names"), contract.joint_names, env_id)
    _same_numbers(
        io,
        f"articulation {name!r} default_joint_pos",
        art.get("default_joint_pos"),
        contract.default_joint_pos,
        env_id,
    )


def _check_action(io: IODescriptors, term: Any, want: ActionTermSpec, env_id: str) -> ActionMap:
    if not isinstance(term, dict):
        raise ConfigError(f"{io.path}: action term {quote(term)} is not a mapping")
    kind = str(term.get("full_path", "")).rsplit(".", 1)[-1]
    label = f"action term {term.get('name', kind)!r}"
    if kind not in ACTION_TERMS:
        raise ConfigError(
            f"{io.path}: {label} ({term.get('full_path')}) is not supported; "
            f"supported: {', '.join(ACTION_TERMS)}"
        )
    if kind != want.kind:
        raise ConfigError(f"{io.path}: {label} is a {kind}; {env_id}'s is a {want.kind}")
    n = len(want.joint_names)
    _same_names(io, label, term.get("joint_names"), want.joint_names, env_id)
    scale = _per_joint(io, term, "scale", n, label)
    if np.any(np.abs(scale - want.scale) > TOLERANCE * max(abs(want.scale), 1.0)):
        raise ConfigError(f"{io.path}: {label} scale {_show(scale)}; {env_id}'s is {want.scale:g}")
    offset = _per_joint(io, term, "offset", n, label)
    _same_numbers(io, f"{label} offset", offset.tolist(), want.offset, env_id)
    return ActionMap(scale, offset, _clip(io, term.get("clip"), n, label))


def _clip(io: IODescriptors, clip: Any, n: int, label: str) -> np.ndarray | None:
    if clip is None:
        return None
    try:
        bounds = np.asarray(clip, dtype=np.float64)
    except (TypeError, ValueError):
        bounds = np.empty(0)
    if bounds.shape != (n, 2) or np.any(np.isnan(bounds)) or np.any(bounds[:, 0] > bounds[:, 1]):
        raise ConfigError(f"{io.path}: {label} clip {quote(clip)} is not {n} [low, high] pairs")
    return bounds


def _per_joint(
    io: IODescriptors, term: Mapping[str, Any], key: str, n: int, label: str
) -> np.ndarray:
    """``scale`` / ``offset``: one number for every joint, or one per joint."""
    value = term.get(key)
    try:
        arr = np.broadcast_to(np.asarray(value, dtype=np.float64), (n,)).copy()
    except (TypeError, ValueError):
        arr = np.full(n, np.nan)
    if not np.all(np.isfinite(arr)):
        raise ConfigError(f"{io.path}: {label} {key} {quote(value)} is not a number or {n} numbers")
    return arr


def _same_names(io: IODescriptors, what: str, got: Any, want: Sequence[str], env_id: str) -> None:
    if not isinstance(got, list) or [str(g) for g in got] != list(want):
        raise ConfigError(
            f"{io.path}: {what} joint_names {quote(got)}; {env_id}'s are {list(want)}"
        )


def _same_numbers(
    io: IODescriptors, what: str, got: Any, want: Sequence[float], env_id: str
) -> None:
    try:
        arr = np.asarray(got, dtype=np.float64).reshape(-1)
    except (TypeError, ValueError):
        arr = np.empty(0)
    if arr.shape != (len(want),) or np.any(~(np.abs(arr - np.asarray(want)) <= TOLERANCE)):
        raise ConfigError(f"{io.path}: {what} {quote(got)}; {env_id}'s is {_show(want)}")


def _number(io: IODescriptors, mapping: Mapping[str, Any], key: str, where: str) -> float:
    value = mapping.get(key)
    if isinstance(value, bool) or not isinstance(value, int | float) or not value > 0:
        raise ConfigError(f"{io.path}: {where}.{key} {quote(value)} is not a positive number")
    return float(value)


def _size(term: Any) -> int:
    """A term's flat size from its ``shape`` (0 when it has none, which the checks refuse)."""
    shape = term.get("shape") if isinstance(term, dict) else None
    if not isinstance(shape, list) or not all(isinstance(s, int) for s in shape):
        return 0
    return int(np.prod(shape)) if shape else 0


def _show(values: Sequence[float] | np.ndarray) -> str:
    arr = np.asarray(values, dtype=np.float64).reshape(-1)
    if arr.size and np.all(arr == arr[0]):
        return f"{arr[0]:g}"
    return "[" + ", ".join(f"{v:.4g}" for v in arr) + "]"
