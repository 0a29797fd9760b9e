"""A training's settings: the sections of a config file (``train``, ``d4pg``, ``emulation``,
``"extends"``), read and checked, with values on top from the command line's flags or a Python
call's keywords, as one ``TrainSetup``.

``robogym-ray train`` (``command.py``), ``robogym_ray.train`` (``api.py``), a sweep's trials and
``experiments/`` all read their settings here; nothing here parses a command line.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from robogym_ray.config import check_fields, check_keys, flags_of, merge_config, quote, read_json
from robogym_ray.errors import ConfigError
from robogym_ray.learner.config import D4PGConfig
from robogym_ray.robots.emulation import EmulationConfig
from robogym_ray.training.config import TrainConfig

SECTIONS = {"train": TrainConfig, "d4pg": D4PGConfig, "emulation": EmulationConfig}
"""Keys a config file may hold, and the config class whose fields each section holds."""


@dataclass(frozen=True)
class TrainSetup:
    """Everything a training was asked for (``robogym-ray train``'s flags and config file, or
    ``robogym_ray.train``'s arguments)."""

    train: TrainConfig
    d4pg: dict[str, Any]
    """D4PGConfig overrides on top of the task's preset."""
    emulation: EmulationConfig
    """What the emulated workers' robots differ by (used when train.emulated_workers > 0)."""


def read_sections(path: str | Path, _chain: tuple[Path, ...] = ()) -> dict[str, dict[str, Any]]:
    """The sections of a config file ({"train": {...}, "d4pg": {...}, "emulation": {...}}).

    A file may name another with ``"extends": "base.json"`` (a path relative to the file): it
    starts from the base's sections and overrides them field by field, so a variant of a recipe
    holds only what it changes and the two cannot drift apart unnoticed.
    """
    path = Path(path)
    chain = (*_chain, path.resolve())
    if chain[-1] in _chain:
        raise ConfigError(f"{path}: 'extends' forms a cycle: {' -> '.join(map(str, chain))}")
    return sections_of(read_json(path), str(path), path.parent, chain)


def sections_of(
    data: object, source: str, base_dir: Path, chain: tuple[Path, ...] = ()
) -> dict[str, dict[str, Any]]:
    """The sections of a config's JSON object (a file's, or the same dict given in Python),
    each checked against its config class; ``"extends"`` is read relative to ``base_dir``.
    ``source`` names the config in errors."""
    if not isinstance(data, dict):
        raise ConfigError(
            f"{source}: expected a JSON object with keys among {', '.join(SECTIONS)} and "
            f"'extends', got a JSON {type(data).__name__}"
        )
    check_keys(data, (*SECTIONS, "extends"), source, "top-level key(s)")
    for name, section in data.items():
        if name != "extends" and not isinstance(section, dict):
            raise ConfigError(f"{source}: section {name!r} must be a JSON object")
        if name != "extends":
            # Each file is checked on its own, so an error names the file that holds the key.
            check_fields(SECTIONS[name], section, f"{source}: {name}")
    base: dict[str, dict[str, Any]] = {name: {} for name in SECTIONS}
    if "extends" in data:
        parent = data["extends"]
        if not isinstance(parent, str) or not parent:
            raise ConfigError(
                f"{source}: 'extends' must be a config file name, got {quote(parent)}"
            )
        try:
            base = read_sections(base_dir / parent, chain)
        except ConfigError as exc:
            raise ConfigError(f"{source} extends {parent}: {exc}") from None
    return {name: {**base[name], **data.get(name, {})} for name in SECTIONS}


def setup_of(
    sections: Mapping[str, Mapping[str, Any]],
    source: str,
    train: Mapping[str, Any] | None = None,
    emulation: Mapping[str, Any] | None = None,
    d4pg: Mapping[str, Any] | None = None,
    flagged: bool = False,
) -> TrainSetup:
    """A config's ``sections`` with ``train``, ``emulation`` and ``d4pg`` values on top (the
    command line's flags, a Python call's keywords). ``flagged``: those values came as flags,
    so an error about one names the flag (``--workers 0``), not the field."""
    train, emulation, d4pg = dict(train or {}), dict(emulation or {}), dict(d4pg or {})
    check_fields(D4PGConfig, d4pg, f"{source}: d4pg")
    return TrainSetup(
        train=merge_config(TrainConfig, {**sections.get("train", {}), **train}, source,
                           flags=flags_of(train) if flagged else None),
        d4pg={**sections.get("d4pg", {}), **d4pg},
        emulation=merge_config(EmulationConfig, {**sections.get("emulation", {}), **emulation},
                               source, flags=flags_of(emulation, "emu-") if flagged else None),
    )  # fmt: skip
