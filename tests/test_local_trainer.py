"""The single-process trainer's CLI (python -m robogym_ray.training.local): presets,
overrides and field docstrings as help."""

from __future__ import annotations

from robogym_ray.config import field_docs
from robogym_ray.learner.config import D4PGConfig
from robogym_ray.training.local import PRESETS, build_parser, parse_args


def test_preset_applies_and_flags_override_it() -> None:
    run, cfg = parse_args(
        [
            "--env",
            "Pendulum-v1",
            "--steps",
            "10",
            "--critic-hidden",
            "8",
            "8",
            "--no-prioritized",
        ]
    )
    assert run.steps == 10 and run.env == "Pendulum-v1"
    assert cfg.v_min == PRESETS["Pendulum-v1"]["v_min"]
    assert cfg.critic_hidden == (8, 8) and cfg.prioritized is False


def test_no_preset_gives_defaults() -> None:
    _, cfg = parse_args(["--preset", "none"])
    assert cfg == D4PGConfig()


def test_every_config_field_is_documented_in_help() -> None:
    docs = field_docs(D4PGConfig)
    assert set(docs) == set(D4PGConfig.__dataclass_fields__)
    help_text = " ".join(build_parser().format_help().split())  # undo argparse wrapping
    assert docs["num_atoms"] in help_text and docs["v_min"] in help_text
