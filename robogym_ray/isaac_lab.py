"""Policies trained in Isaac Lab, as its rsl_rl ``play.py`` exports them, run on our robots.

``play.py`` writes two files into ``logs/rsl_rl/<task>/<run>/exported/``:

* ``policy.pt`` - TorchScript of a module whose ``forward(obs)`` is ``actor(normalizer(obs))``:
  the actor MLP (``actor.0.weight`` ... ) behind the empirical observation normaliser (or an
  identity), so the file takes raw observations;
* ``policy.onnx`` - the same network with input ``obs`` ``[1, N]`` and output ``actions``
  ``[1, M]`` (batch fixed at 1).

Both answer raw actions in the env's own units (IsaacReach: joint offsets before its x0.5
scale), not [-1, 1] as our own exported policies do. ``IsaacLabPolicy`` maps them onto
[-1, 1] by the env's action bounds, so the one greedy-episode loop clips them at the env's
bounds (robo-gym 2.1.0 does not clip them: docs/protocol.md). The ONNX file needs only
``onnxruntime`` (the ``onnx`` extra), not torch.

With Isaac Lab 3's ``IO_descriptors.yaml`` beside it (``io_descriptors``), the file is checked
against the env before the first action (``robogym_ray.envs.io_descriptors``) and its action term's
scale, offset and clip are what turns the network's output into the joint command.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import numpy as np

from robogym_ray.envs.io_descriptors import check as check_io
from robogym_ray.envs.io_descriptors import load as io_descriptors_load
from robogym_ray.errors import ConfigError
from robogym_ray.learner.behaviour import from_env_action
from robogym_ray.onnx_policy import OnnxPolicy
from robogym_ray.text import reason

SUFFIXES = (".pt", ".onnx")


class IsaacLabPolicy:
    """An exported Isaac Lab policy: raw observations -> raw actions (env units).

    Args:
        path: ``policy.pt`` or ``policy.onnx``.
        io_descriptors: Isaac Lab 3's ``IO_descriptors.yaml`` of the same run, or None.
    """

    def __init__(self, path: str | Path, io_descriptors: str | Path | None = None) -> None:
        self.path = Path(path)
        if self.path.suffix not in SUFFIXES:
            raise ConfigError(
                f"{self.path}: an Isaac Lab policy is play.py's policy.pt (TorchScript) or "
                f"policy.onnx; got a {self.path.suffix or 'suffix-less'} file"
            )
        if not self.path.is_file():
            raise ConfigError(f"{self.path}: no such file")
        if self.path.suffix == ".pt":
            self._run, self.obs_dim, self.act_dim = _load_torchscript(self.path)
        else:
            onnx = OnnxPolicy(self.path)
            self._run, self.obs_dim, self.act_dim = onnx, onnx.obs_dim, onnx.act_dim
        self.io = None if io_descriptors is None else io_descriptors_load(io_descriptors)
        if self.io is not None and self.io.obs_size != self.obs_dim:
            raise ConfigError(
                f"{self.io.path}: its observation terms add up to {self.io.obs_size} values; "
                f"{self.path} takes {self.obs_dim}"
            )

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        return self._run(np.asarray(obs, dtype=np.float32).reshape(1, -1)).reshape(-1)

    def unit_policy(self, env: Any) -> Any:
        """This policy for the greedy-episode loop, which takes actions in [-1, 1]. With IO
        descriptors, first the check against ``env`` (ConfigError on a mismatch, before any
        action); then each output goes through the file's action term and back into the env's
        action units (``(processed - env offset) / env scale``)."""
        low = env.action_space.low.astype(np.float64)
        high = env.action_space.high.astype(np.float64)
        if self.io is None:
            return lambda obs: from_env_action(self(obs), low, high)
        env_id = env.spec.id if env.spec is not None else type(env.unwrapped).__name__
        declare = getattr(env.unwrapped, "isaac_io", None)
        if declare is None:
            raise ConfigError(
                f"{env_id} declares no Isaac Lab observation and action terms: --io-descriptors "
                "works with the IsaacReachUR10 and IsaacDeployReachUR10e ids"
            )
        contract = declare()
        action_map = check_io(self.io, contract, env_id)
        env_offset = np.asarray(contract.action.offset, dtype=np.float64)
        scale = contract.action.scale

        def act(obs: np.ndarray) -> np.ndarray:
            raw = (action_map.processed(self(obs)) - env_offset) / scale
            return from_env_action(raw, low, high)

        return act


def _load_torchscript(path: Path) -> tuple[Any, int, int]:
    import torch

    try:
        module = torch.jit.load(str(path), map_location="cpu")
    except (RuntimeError, ValueError, OSError) as exc:
        raise ConfigError(
            f"{path}: not a TorchScript file ({reason(str(exc)) or type(exc).__name__})"
        ) from None
    # The actor's Linear layers are the 2-D "actor.<i>.weight" parameters, in order.
    layers = {}
    for name, value in module.named_parameters():
        match = re.fullmatch(r"actor\.(\d+)\.weight", name)
        if match is not None and value.dim() == 2:
            layers[int(match.group(1))] = value
    if not layers:
        raise ConfigError(
            f"{path}: a TorchScript file without actor.<i>.weight layers - not an rsl_rl export "
            "(Isaac Lab's play.py writes policy.pt with the actor behind its normaliser)"
        )
    if any(name.startswith("rnn.") for name, _ in module.named_parameters()):
        # Its actor's input is the RNN's hidden state: the sizes below would be wrong.
        raise ConfigError(f"{path}: a recurrent rsl_rl policy (rnn.*); only MLP actors run here")
    ordered = [w for _, w in sorted(layers.items())]
    obs_dim, act_dim = int(ordered[0].shape[1]), int(ordered[-1].shape[0])
    module.eval()

    def run(obs: np.ndarray) -> np.ndarray:
        with torch.no_grad():
            return module(torch.from_numpy(obs)).numpy()

    return run, obs_dim, act_dim
