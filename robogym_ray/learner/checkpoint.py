"""The checkpoint layout, in one place: what a learner checkpoint and a policy file hold, where
they live in a run, and how they are read, written and checked.

``RUN/checkpoints/learner.pt`` (``CHECKPOINT_NAME``) is a ``torch.save`` dict::

    {"nets": {"policy", "critic", "target_policy", "target_critic"[, "policy_average"]},
     "opts": {"policy", "critic"}, "num_steps": int, "torch_rng": tensor}

with the replay, when kept, beside it as ``learner.pt.replay.npz`` (``replay_path``): plain
arrays only, loaded without pickle. A policy file (``policy-best.pt``, snapshot selection) has
the same ``nets.policy`` and nothing else of the learner, so ``evaluate`` and ``export`` read
both alike (``policy_weights``). Every file is written to a temporary name and renamed, so a
crash never leaves half a file.
"""

from __future__ import annotations

import json
import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import torch

from robogym_ray.errors import ConfigError

CHECKPOINT_NAME = "learner.pt"
"""The learner's checkpoint in a run's ``checkpoints/`` folder."""
BEST_POLICY_NAME = "policy-best.pt"
"""The policy snapshot selection keeps (``--select-episodes``)."""
REPLAY_SUFFIX = ".replay.npz"
NETS = ("policy", "critic", "target_policy", "target_critic", "policy_average")
_RNG_KEY = "rng_state"  # the replay's numpy RNG state, stored as JSON text (no pickle)


def replay_path(checkpoint: str | os.PathLike) -> Path:
    """``learner.pt`` -> ``learner.pt.replay.npz``."""
    return Path(f"{checkpoint}{REPLAY_SUFFIX}")


def write_atomic(path: str | os.PathLike, state: Mapping[str, Any]) -> Path:
    """``torch.save`` to a temporary name beside ``path``, then rename it into place."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    torch.save(dict(state), tmp)
    os.replace(tmp, path)
    return path


def read(path: str | os.PathLike, device: str | torch.device = "cpu") -> dict[str, Any]:
    """A checkpoint or policy file (tensors only: ``weights_only``), or a ConfigError."""
    try:
        state = torch.load(path, map_location=device, weights_only=True)
    except (OSError, RuntimeError, EOFError, ValueError) as exc:
        raise ConfigError(f"cannot read checkpoint {path}: {exc}") from None
    if not isinstance(state, dict) or not isinstance(state.get("nets"), dict):
        raise ConfigError(f"{path} is not a D4PGLearner checkpoint (no nets)")
    return state


def policy_weights(state: Mapping[str, Any], online: bool = False) -> tuple[str, dict]:
    """``(name, state dict)`` of the policy to run: the Polyak average when the run kept one
    (what its evaluator scored), else the online policy; ``online`` forces the online one."""
    nets = state["nets"]
    name = "policy" if online or "policy_average" not in nets else "policy_average"
    if name not in nets:
        raise ConfigError(f"checkpoint has no nets.{name} (nets: {sorted(nets)})")
    return name, nets[name]


def write_policy(path: str | os.PathLike, weights: Mapping[str, np.ndarray], **extra: Any) -> Path:
    """A policy file: ``nets.policy`` from numpy ``weights``, plus ``extra`` entries."""
    nets = {"policy": {k: torch.from_numpy(np.array(v)) for k, v in weights.items()}}
    return write_atomic(path, {"nets": nets, **extra})


def learner_state(learner: Any) -> dict[str, Any]:
    """What a learner checkpoint holds of ``learner`` (a ``D4PGLearner``)."""
    nets = {name: getattr(learner, name) for name in NETS}
    return {
        "nets": {name: net.state_dict() for name, net in nets.items() if net is not None},
        "opts": {"policy": learner.policy_opt.state_dict(),
                 "critic": learner.critic_opt.state_dict()},
        "num_steps": learner.num_steps,
        "torch_rng": torch.get_rng_state(),
    }  # fmt: skip


def write_replay(path: str | os.PathLike, replay_state: Mapping[str, Any]) -> None:
    arrays = dict(replay_state)
    arrays[_RNG_KEY] = np.array(json.dumps(arrays[_RNG_KEY]))
    with open(path, "wb") as f:  # np.savez would append .npz to a name without it
        np.savez(f, **arrays)


def read_replay(path: str | os.PathLike) -> dict[str, Any]:
    """The replay state ``write_replay`` wrote; never unpickles (a file could run code)."""
    try:
        with np.load(path, allow_pickle=False) as data:
            state = dict(data)
    except ValueError as exc:  # object arrays need pickle: an older or foreign file
        raise ConfigError(
            f"{path}: a replay file with pickled data is not loaded ({exc}); "
            "it was written by an older robogym-ray or by something else"
        ) from None
    state[_RNG_KEY] = json.loads(str(state[_RNG_KEY]))
    return state
