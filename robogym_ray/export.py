"""Policies out of training: from a learner checkpoint, and as TorchScript or ONNX for the
robot PC.

``robogym-ray export CHECKPOINT OUT`` writes ``OUT`` (a TorchScript module: float32 observations
``(batch, obs_dim)`` -> actions in [-1, 1] ``(batch, act_dim)``; an ONNX model with input ``obs``
and output ``actions`` when OUT ends in ``.onnx``) and ``OUT.json`` next to it
(``sidecar_path``): format, dimensions, env id, the env's action bounds and where it came from.
The robot PC needs only torch to run the TorchScript file, only onnxruntime to run the ONNX one
(no robogym_ray, no Ray); ``robogym-ray run-policy`` drives a robot server with either.

A checkpoint is ``learner.pt`` as ``D4PGLearner.save`` writes it; the policy's architecture is
read back from its weights (hidden sizes, LayerNorm), so no config is needed to load it.
"""

from __future__ import annotations

import argparse
import io
import json
import re
import sys
from dataclasses import MISSING, asdict, dataclass, fields
from pathlib import Path
from typing import Any

import numpy as np
import torch
from torch import nn

from robogym_ray.config import check_dir_path, check_fields, quote, read_json
from robogym_ray.errors import ConfigError
from robogym_ray.learner.checkpoint import CHECKPOINT_NAME, RUN_CHECKPOINT, policy_weights, read
from robogym_ray.storage import RunStorage, is_uri, local_file, staged_write, write_bytes
from robogym_ray.text import clip_text, first_sentence

FORMAT = "robogym-ray-policy/torchscript-v1"
ONNX_FORMAT = "robogym-ray-policy/onnx-v1"
"""An ``OUT.onnx`` export: the same policy as ONNX (input ``obs``, output ``actions``)."""


@dataclass(frozen=True)
class PolicyInfo:
    """What the sidecar JSON holds."""

    obs_dim: int
    act_dim: int
    policy_hidden: tuple[int, ...]
    layer_norm: bool
    env_id: str | None = None
    action_low: tuple[float, ...] | None = None
    action_high: tuple[float, ...] | None = None
    source: str = ""
    format: str = FORMAT


def sidecar_path(policy_file: str | Path) -> Path:
    """``policy.pt`` -> ``policy.pt.json``."""
    return Path(str(policy_file) + ".json")


def policy_from_state_dict(state: dict[str, torch.Tensor]) -> tuple[nn.Module, PolicyInfo]:
    """Rebuild ``networks.Policy`` from its weights (architecture inferred, strict load)."""
    from robogym_ray.learner.networks import Policy

    layers: dict[int, torch.Tensor] = {}
    for key, value in state.items():
        match = re.fullmatch(r"net\.(\d+)\.weight", key)
        if match is None:
            continue
        layers[int(match.group(1))] = value
    if not all(isinstance(w, torch.Tensor) for w in layers.values()):
        raise ConfigError("not a policy state dict: a net.<i>.weight that is not a tensor")
    linear = [w for _, w in sorted(layers.items()) if w.dim() == 2]
    if not linear:
        keys = quote(sorted(map(str, state))) if isinstance(state, dict) else quote(state)
        raise ConfigError(f"not a policy state dict: no net.<i>.weight matrices in {keys}")
    layer_norm = any(w.dim() == 1 for w in layers.values())
    hidden = tuple(int(w.shape[0]) for w in linear[:-1])
    obs_dim, act_dim = int(linear[0].shape[1]), int(linear[-1].shape[0])
    try:
        policy = Policy(obs_dim, act_dim, hidden, layer_norm)
        policy.load_state_dict(state)
    except (RuntimeError, ValueError, TypeError) as exc:  # shapes that make no policy
        raise ConfigError(f"not a policy state dict: {clip_text(str(exc), 300)}") from None
    policy.eval().requires_grad_(False)
    return policy, PolicyInfo(obs_dim, act_dim, hidden, layer_norm)


def load_checkpoint_policy(
    checkpoint: str | Path, online: bool = False
) -> tuple[nn.Module, PolicyInfo]:
    """The policy of a ``learner.pt`` (only the policy weights are used).

    That is the Polyak-averaged policy when the run kept one (``policy_average_tau > 0``: the
    one its evaluator scored), else the online one; ``online=True`` always takes the online
    policy. ``PolicyInfo.source`` says which: ``PATH`` or ``PATH#policy_average``.
    """
    name, policy_state = policy_weights(read(checkpoint), online)
    policy, info = policy_from_state_dict(policy_state)
    source = str(checkpoint) if name == "policy" else f"{checkpoint}#{name}"
    return policy, PolicyInfo(**{**asdict(info), "source": source})


def env_id_of_run(checkpoint: str | Path) -> str | None:
    """The env id of the training run a ``RUN/checkpoints/learner.pt`` belongs to, if known."""
    config = Path(checkpoint).resolve().parent.parent / "config.json"
    try:
        task = read_json(config)["train"]["task"]
    except (ConfigError, KeyError, TypeError):
        return None
    if not isinstance(task, str):
        return None
    from robogym_ray.training.presets import resolve_task

    try:
        return resolve_task(task).env_id
    except ConfigError:
        return None


def env_spaces(env_id: str) -> tuple[Any, Any]:
    """The env's observation and action spaces (making the env starts no server: that happens
    on reset). ConfigError for an id gymnasium does not know."""
    import gymnasium as gym

    import robogym_ray.envs  # noqa: F401 - registers the ids

    try:
        env = gym.make(env_id)
    except gym.error.Error as exc:  # an id gymnasium does not know
        raise ConfigError(f"env id {quote(env_id)}: {clip_text(str(exc), 200)}") from None
    try:
        return env.observation_space, env.action_space
    finally:
        env.close()


def action_bounds(env_id: str) -> tuple[tuple[float, ...], tuple[float, ...]]:
    """The env's action Box."""
    space = env_spaces(env_id)[1]
    return tuple(map(float, space.low)), tuple(map(float, space.high))


ONLINE_WEIGHTS_HELP = (
    "Use the checkpoint's online policy even when the run kept a Polyak-averaged one "
    "(policy_average_tau > 0), which is used by default."
)


def export_policy(
    checkpoint: str | Path, out: str | Path, env_id: str | None = None, online: bool = False
) -> PolicyInfo:
    """Write the checkpoint's policy as TorchScript to ``out`` plus its sidecar JSON."""
    if Path(out).is_dir():  # checked before anything is loaded or written
        raise ConfigError(f"export OUT {out} is a directory; name the file to write")
    check_dir_path(Path(out).parent, "export OUT's directory")
    checkpoint = local_file(checkpoint, "checkpoint")  # an object store's: downloaded once
    policy, info = load_checkpoint_policy(checkpoint, online)
    env_id = env_id or env_id_of_run(checkpoint)
    low, high = action_bounds(env_id) if env_id else (None, None)
    info = PolicyInfo(**{**asdict(info), "env_id": env_id, "action_low": low, "action_high": high})
    out = Path(out)
    # Serialized in memory, written beside OUT and renamed into place only once its sidecar is
    # written: a full disk leaves no half-written file, and a failed re-export leaves the
    # previous OUT as it was (an OUT without its sidecar would read as a learner checkpoint).
    buffer = io.BytesIO()
    if out.suffix == ".onnx":  # for a robot PC with onnxruntime only
        from robogym_ray.onnx_policy import write_onnx

        info = PolicyInfo(**{**asdict(info), "format": ONNX_FORMAT})
        write_onnx(policy, info.obs_dim, buffer)
    else:
        # Tracing is exact here: the policy is a fixed MLP with no data-dependent control flow.
        torch.jit.save(torch.jit.trace(policy, torch.zeros(1, info.obs_dim)), buffer)
    with staged_write(out, buffer.getbuffer(), "exported policy"):
        sidecar = json.dumps(asdict(info), indent=2).encode()
        write_bytes(sidecar_path(out), sidecar, "exported policy's sidecar")
    return info


def load_exported(path: str | Path) -> tuple[Any, PolicyInfo]:
    """An exported policy and its sidecar, both checked: the module (TorchScript, or an
    ``OnnxPolicy`` for ``.onnx``) is run once on zeros and must answer ``(1, act_dim)`` (a
    ConfigError saying what is wrong, never a traceback)."""
    sidecar = sidecar_path(path)
    data = read_json(sidecar, "policy sidecar")
    if not isinstance(data, dict):
        raise ConfigError(f"{sidecar}: expected a JSON object, got {quote(data)}")
    expected = ONNX_FORMAT if Path(path).suffix == ".onnx" else FORMAT
    if data.get("format") != expected:
        raise ConfigError(f"{sidecar}: format {quote(data.get('format'))}, expected {expected}")
    check_fields(PolicyInfo, data, str(sidecar))
    missing = sorted(set(_REQUIRED) - set(data))
    if missing:
        raise ConfigError(f"{sidecar}: no {', '.join(missing)}")
    info = PolicyInfo(**{k: tuple(v) if isinstance(v, list) else v for k, v in data.items()})
    if expected == ONNX_FORMAT:
        from robogym_ray.onnx_policy import OnnxPolicy

        onnx = OnnxPolicy(path)  # a file onnxruntime cannot read is a one-line ConfigError
        shape = tuple(onnx(np.zeros((1, info.obs_dim), np.float32)).shape)
        _check_answer(path, info, shape)
        return onnx, info
    try:
        module = torch.jit.load(str(path), map_location="cpu")
        module.eval()
        with torch.inference_mode():
            shape = tuple(module(torch.zeros(1, info.obs_dim)).shape)
    except (OSError, RuntimeError, ValueError) as exc:  # not TorchScript, truncated, mismatched
        raise ConfigError(f"cannot load exported policy {path}: {first_sentence(exc)}") from None
    _check_answer(path, info, shape)
    return module, info


def _check_answer(path: str | Path, info: PolicyInfo, shape: tuple[int, ...]) -> None:
    if shape != (1, info.act_dim):
        raise ConfigError(
            f"exported policy {path} maps (1, {info.obs_dim}) to {shape}; its sidecar says "
            f"(1, {info.act_dim})"
        )


_REQUIRED = [f.name for f in fields(PolicyInfo) if f.default is MISSING]


class PolicyFunction:
    """``obs -> action in [-1, 1]`` (float32, one observation) for any loaded policy: a torch
    module (checkpoint, TorchScript) or a ``[batch, obs] -> [batch, act]`` array function."""

    def __init__(self, module: Any, info: PolicyInfo) -> None:
        self.module, self.info = module, info
        self._torch = isinstance(module, nn.Module | torch.jit.ScriptModule)

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        batch = np.asarray(obs, dtype=np.float32).reshape(1, -1)
        if not self._torch:
            return np.asarray(self.module(batch))[0].astype(np.float32)
        with torch.inference_mode():
            return self.module(torch.from_numpy(batch))[0].numpy().astype(np.float32)


def run_checkpoint(location: str | Path) -> str | None:
    """The checkpoint in the run folder ``location`` (what a run's summary names as its
    ``files:``; a path or an object store's URI): ``RUN/checkpoints/learner.pt``, the file the
    summary's ``checkpoint`` names, or ``learner.pt`` in a run's ``checkpoints/`` itself.
    None when ``location`` is not a folder (a file, read as it is).

    Raises:
        ConfigError: a folder with no checkpoint.
    """
    location = str(location)
    candidates = (RUN_CHECKPOINT, CHECKPOINT_NAME)
    if is_uri(location):  # an object store has no folders to ask about: look for the files
        store = RunStorage(location)
        return next((store.location(c) for c in candidates if store.exists(c)), None)
    folder = Path(location)
    if not folder.is_dir():
        return None
    for candidate in candidates:
        if (folder / candidate).is_file():
            return str(folder / candidate)
    raise ConfigError(
        f"{location} is a folder with no checkpoint ({RUN_CHECKPOINT} or {CHECKPOINT_NAME}): "
        "give a run folder, a learner.pt or an exported policy"
    )


def policy_argument(location: str) -> str:
    """A command's policy argument as the file to read: a run folder gives its checkpoint
    (``run_checkpoint``), and the command says which file it took (on stderr)."""
    taken = run_checkpoint(location)
    if taken is None:
        return location
    print(f"{location} is a run folder: using its checkpoint {taken}", file=sys.stderr)
    return taken


def load_policy(path: str | Path, online: bool = False) -> PolicyFunction:
    """An exported policy (it has a sidecar) or a learner checkpoint (see
    :func:`load_checkpoint_policy` for ``online``); ``path`` may be an object store's URI."""
    path = local_file(path, "policy")
    if sidecar_path(path).exists():
        if online:
            raise ConfigError(f"{path} is an exported policy; --online-weights needs a learner.pt")
        return PolicyFunction(*load_exported(path))
    module, info = load_checkpoint_policy(path, online)
    return PolicyFunction(module, PolicyInfo(**{**asdict(info), "env_id": env_id_of_run(path)}))


# -- CLI: robogym-ray export -------------------------------------------------------------------
def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "checkpoint", help="A run's folder (its checkpoint is taken) or a learner.pt."
    )
    parser.add_argument(
        "out",
        help="File to write: TorchScript, or ONNX when it ends in .onnx (for onnxruntime on a "
        "robot PC without torch); its sidecar is OUT.json.",
    )
    parser.add_argument(
        "--env-id",
        default=None,
        help="Env id the policy drives (default: from the run's config.json).",
    )
    parser.add_argument("--online-weights", action="store_true", help=ONLINE_WEIGHTS_HELP)


def run(args: argparse.Namespace) -> int:
    checkpoint = policy_argument(args.checkpoint)
    info: Any = export_policy(checkpoint, args.out, args.env_id, args.online_weights)
    print(json.dumps({"out": args.out, "sidecar": str(sidecar_path(args.out)), **asdict(info)}))
    return 0
