"""The checkpoint layout, in one place: what a learner checkpoint and a policy file hold, where
they live in a run, and how they are read, written and checked.

``RUN/checkpoints/learner.pt`` (``CHECKPOINT_NAME``) is a ``torch.save`` dict::

    {"nets": {"policy", "critic", "target_policy", "target_critic"[, "policy_average"]},
     "opts": {"policy", "critic"}, "num_steps": int, "torch_rng": tensor[, "cuda_rng": tensor]}

with the replay, when kept, beside it as ``learner.pt.replay.npz`` (``replay_path``): plain
arrays only, loaded without pickle. A policy file (``policy-best.pt``, snapshot selection) has
the same ``nets.policy`` and nothing else of the learner, so ``evaluate`` and ``export`` read
both alike (``policy_weights``). Every file is written to a temporary name and renamed, so a
crash never leaves half a file; a write that fails (a full disk: ``DiskWriteError``) removes
the temporary one and leaves the file that was there.
"""

from __future__ import annotations

import errno
import io
import json
import os
import pickle
import warnings
import zipfile
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import torch

from robogym_ray.errors import ConfigError
from robogym_ray.storage import replacing, write_bytes
from robogym_ray.text import first_sentence

CHECKPOINT_NAME = "learner.pt"
"""The learner's checkpoint in a run's ``checkpoints/`` folder."""
RUN_CHECKPOINT = f"checkpoints/{CHECKPOINT_NAME}"
"""The learner's checkpoint in a run's folder (what its summary's ``checkpoint`` names)."""
BEST_POLICY_NAME = "policy-best.pt"
"""The policy snapshot selection keeps (``--select-episodes``)."""
REPLAY_SUFFIX = ".replay.npz"
"""Appended to a checkpoint's path for the file holding its replay buffer."""
NETS = ("policy", "critic", "target_policy", "target_critic", "policy_average")
_RNG_KEY = "rng_state"  # the replay's numpy RNG state, stored as JSON text (no pickle)


def replay_path(checkpoint: str | os.PathLike) -> Path:
    """``learner.pt`` -> ``learner.pt.replay.npz``."""
    return Path(f"{checkpoint}{REPLAY_SUFFIX}")


def write_atomic(
    path: str | os.PathLike, state: Mapping[str, Any], what: str = "checkpoint"
) -> Path:
    """``torch.save`` to a temporary name beside ``path``, then rename it into place; see
    ``write_bytes`` for what a failure leaves."""
    buffer = io.BytesIO()
    # Serialized in memory: torch's own file writer turns a full disk into a RuntimeError
    # ("unexpected pos", "basic_ios::clear: iostream error") that has lost the errno.
    torch.save(dict(state), buffer)
    return write_bytes(path, buffer.getbuffer(), what)


def read(path: str | os.PathLike, device: str | torch.device = "cpu") -> dict[str, Any]:
    """A checkpoint or policy file (tensors only: ``weights_only``), or a ConfigError."""
    try:
        if os.path.getsize(path) == 0:
            raise EOFError("empty file (0 bytes)")
        # torch warns about some pickle protocols on the way; the error below says it all.
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            state = torch.load(path, map_location=device, weights_only=True)
    except (OSError, RuntimeError, EOFError, ValueError, pickle.UnpicklingError) as exc:
        raise ConfigError(f"cannot read checkpoint {path}: {_why_unreadable(exc)}") from None
    if not isinstance(state, dict) or not isinstance(state.get("nets"), dict):
        raise ConfigError(f"{path} is not a D4PGLearner checkpoint (no nets)")
    return state


def _why_unreadable(exc: BaseException) -> str:
    """``torch.load``'s reason in one short line (its own messages run to paragraphs)."""
    if isinstance(exc, pickle.UnpicklingError):
        # Also a pickle of Python objects, which weights_only never runs.
        return "not a torch checkpoint of tensors (wrong format)"
    first = first_sentence(exc)
    if isinstance(exc, EOFError):
        return first if "empty" in first else f"truncated ({first})"
    # PytorchStreamReader on a cut or damaged zip archive: RuntimeError, or EINVAL from a seek
    # past the end that the archive's directory asked for.
    if isinstance(exc, RuntimeError) or getattr(exc, "errno", None) == errno.EINVAL:
        return f"truncated or corrupt ({first[:200]})"
    return first[:200]


LEARNER_KEYS = ("nets.policy", "nets.critic", "nets.target_policy", "nets.target_critic",
                "opts.policy", "opts.critic", "num_steps", "torch_rng")  # fmt: skip
"""What ``D4PGLearner.restore`` reads of a learner checkpoint (``learner_state`` writes)."""


def check_learner_state(state: Mapping[str, Any], path: str | os.PathLike) -> None:
    """ConfigError naming what a learner checkpoint lacks (a policy file has only nets.policy)."""
    missing = []
    for key in LEARNER_KEYS:
        node: Any = state
        for part in key.split("."):
            node = node.get(part) if isinstance(node, Mapping) else None
        if node is None:
            missing.append(key)
    if missing:
        raise ConfigError(f"{path} is not a complete learner checkpoint: no {', '.join(missing)}")
    rng, steps = state["torch_rng"], state["num_steps"]
    if not isinstance(rng, torch.Tensor) or rng.shape != torch.get_rng_state().shape:
        raise ConfigError(f"{path}: torch_rng is not a torch RNG state")
    if isinstance(steps, bool) or not isinstance(steps, int) or steps < 0:
        raise ConfigError(f"{path}: num_steps = {str(steps)[:40]}; expected an integer >= 0")


def check_replay(path: str | os.PathLike) -> None:
    """ConfigError unless ``path`` is a replay file ``read_replay`` can load: a readable
    archive with every array (the directory only is read, not the arrays)."""
    from robogym_ray.learner.replay import FIELDS

    try:
        with np.load(path, allow_pickle=False) as data:
            names = set(data.files) if hasattr(data, "files") else set()
    except (OSError, ValueError, EOFError, zipfile.BadZipFile) as exc:
        reason = (str(exc).strip().splitlines() or [type(exc).__name__])[0][:200]
        raise ConfigError(f"cannot read replay {path}: {reason}") from None
    missing = sorted({*FIELDS, "priorities", "counters", "max_priority", _RNG_KEY} - names)
    if missing:
        raise ConfigError(f"{path} is not a replay file: no {', '.join(missing)}")


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
    return write_atomic(path, {"nets": nets, **extra}, what="policy file")


def learner_state(learner: Any) -> dict[str, Any]:
    """What a learner checkpoint holds of ``learner`` (a ``D4PGLearner``)."""
    nets = {name: getattr(learner, name) for name in NETS}
    return {
        "nets": {name: net.state_dict() for name, net in nets.items() if net is not None},
        "opts": {"policy": learner.policy_opt.state_dict(),
                 "critic": learner.critic_opt.state_dict()},
        "num_steps": learner.num_steps,
        "torch_rng": torch.get_rng_state(),
        # The whole step draws its samples from the device's generator: resumed, it goes on.
        **({"cuda_rng": torch.cuda.get_rng_state()} if learner.device.type == "cuda" else {}),
    }  # fmt: skip


def write_replay(path: str | os.PathLike, replay_state: Mapping[str, Any]) -> None:
    """The replay's arrays to ``path`` (atomically, like ``write_bytes``: on a failure, no
    temporary file and the old ``path`` untouched)."""
    arrays = dict(replay_state)
    arrays[_RNG_KEY] = np.array(json.dumps(arrays[_RNG_KEY]))
    # Streamed to the file, not through memory: a replay can be gigabytes.
    with replacing(Path(path), "replay") as tmp, open(tmp, "wb") as f:
        np.savez(f, **arrays)  # to an open file: np.savez would append .npz to a bare name
        f.flush()
        os.fsync(f.fileno())


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
