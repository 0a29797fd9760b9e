"""The Python entry to a training: ``robogym_ray.train(...)`` runs what ``robogym-ray train``
runs, from the same settings, and returns its summary.

The settings come as a config file's path or its dict (``{"train": {...}, "d4pg": {...},
"emulation": {...}}``, ``"extends"`` relative to the working directory), as a ``TrainConfig``,
or as a ``TrainSetup`` (what ``robogym-ray train``'s flags and config file make), with keywords
on top: ``TrainConfig`` fields, ``d4pg=`` (a dict of ``D4PGConfig`` fields over the task's
preset, or a whole ``D4PGConfig``) and ``emulation=``. Everything is checked, as the command
line checks it, before Ray starts.

>>> summary = robogym_ray.train({"train": {"task": "pendulum"}}, total_steps=2000,
...                             d4pg={"sigma": 0.3})
>>> summary["ended"], summary["eval/success_rate"], summary["checkpoint"]
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from robogym_ray.config import KEYWORDS, Words
from robogym_ray.errors import ConfigError
from robogym_ray.learner.config import D4PGConfig
from robogym_ray.robots.emulation import EmulationConfig
from robogym_ray.training.config import TrainConfig
from robogym_ray.training.settings import TrainSetup, read_sections, sections_of, setup_of

Settings = str | Path | Mapping[str, Any] | TrainConfig | TrainSetup | None
"""What ``train`` and ``settings`` take: a config file, its dict, or the config objects."""


def settings(
    config: Settings = None,
    /,
    *,
    d4pg: Mapping[str, Any] | D4PGConfig | None = None,
    emulation: Mapping[str, Any] | EmulationConfig | None = None,
    **train: Any,
) -> TrainSetup:
    """The ``TrainSetup`` of ``config`` with the keywords on top (``train``: ``TrainConfig``
    fields, as the command line's flags override a config file's ``train`` section).

    Raises:
        ConfigError: an unknown key or a bad value, named with where it came from.
    """
    if isinstance(d4pg, D4PGConfig):
        d4pg = dataclasses.asdict(d4pg)
    if isinstance(emulation, EmulationConfig):
        emulation = dataclasses.asdict(emulation)
    if isinstance(config, TrainSetup):
        sections: dict[str, dict[str, Any]] = {
            "train": dataclasses.asdict(config.train),
            "d4pg": dict(config.d4pg),
            "emulation": dataclasses.asdict(config.emulation),
        }
        source = "settings"
    elif isinstance(config, TrainConfig):
        sections, source = {"train": dataclasses.asdict(config)}, "TrainConfig"
    elif isinstance(config, (str, Path)):
        sections, source = read_sections(config), str(config)
    elif isinstance(config, Mapping):
        sections, source = sections_of(dict(config), "config", Path.cwd()), "config"
    elif config is None:
        sections, source = {}, "keywords"
    else:
        raise ConfigError(
            f"train(): expected a config file, its dict, a TrainConfig or a TrainSetup, got a "
            f"{type(config).__name__}"
        )
    return setup_of(sections, source, train, emulation, d4pg)


def train(
    config: Settings = None,
    /,
    *,
    d4pg: Mapping[str, Any] | D4PGConfig | None = None,
    emulation: Mapping[str, Any] | EmulationConfig | None = None,
    **fields: Any,
) -> dict[str, Any]:
    """Run one training (``settings(config, ...)``) to its end on a local Ray (started and
    stopped here unless one is running, or ``address=`` names a cluster) and return its
    summary, the dict ``summary.json`` holds: ``ended``, ``env_steps``, ``eval/success_rate``,
    ``checkpoint`` (the learner's, for ``evaluate``, ``export`` and ``init_from``), ...

    Raises:
        ConfigError: bad settings, before Ray starts and before any file is written; it names
            them as keywords (``workers=8``, ``resume=True``).
        RunStoppedError: a file of the run could not be written (the summary says what was
            kept).
    """
    return run_checked(settings(config, d4pg=d4pg, emulation=emulation, **fields), KEYWORDS)


def run_checked(setup: TrainSetup, words: Words = KEYWORDS) -> dict[str, Any]:
    """``setup`` checked (its errors naming the settings in ``words``: ``train``'s keywords,
    or ``robogym-ray train``'s flags) and run: ``train``'s and the command's one way in."""
    from robogym_ray.training.run import run_training
    from robogym_ray.training.setup import check_inputs

    check_inputs(setup, words=words)  # a bad input costs no Ray start and leaves no folder
    return run_training(setup.train, setup.d4pg, setup.emulation, words=words)
