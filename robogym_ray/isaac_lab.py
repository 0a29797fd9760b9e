"""Policies trained in Isaac Lab, as its rsl_rl ``play.py`` exports them, run on our robots.

``play.py`` writes two files into ``logs/rsl_rl/<task>/<run>/exported/``:

* ``policy.pt`` - TorchScript of a module whose ``forward(obs)`` is ``actor(normalizer(obs))``:
  the actor MLP (``actor.0.weight`` ... ) behind the empirical observation normaliser (or an
  identity), so the file takes raw observations;
* ``policy.onnx`` - the same network with input ``obs`` ``[1, N]`` and output ``actions``
  ``[1, M]`` (batch fixed at 1).

Both answer raw actions in the env's own units (IsaacReach: joint offsets before its x0.5
scale), not [-1, 1] as our own exported policies do. The ONNX file needs only ``onnxruntime``
(the ``onnx`` extra), not torch.

The network's output reaches the env through Isaac ROS's action decoder
(``isaac_manipulator_ur_dnn_policy``), step by step (``IsaacRosDecoder``):

1. **clamp** to the env's action bounds ([-1, 1] for the deploy reach, as Isaac ROS clamps;
   robo-gym 2.1.0 does not clamp IsaacReach's: docs/protocol.md);
2. **EMA**, optional: ``a_t = alpha x clamped + (1 - alpha) x a_t-1`` (alpha 1.0, Isaac ROS's
   default: none), from zero at each episode's start;
3. **scale** (and offset, clip) by the action term of Isaac Lab 3's ``IO_descriptors.yaml``
   when one is given (``io_descriptors``: checked against the env before the first action,
   ``robogym_ray.envs.io_descriptors``), else by the env's own action map;
4. **stream**: the env sends the target (deploy reach: measured joints + 0.0625 x a_t) to the
   robot server, one per step at the env's rate (60 Hz, the servo holding each until the next).
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import numpy as np

from robogym_ray.envs.io_descriptors import ActionMap, IOContract
from robogym_ray.envs.io_descriptors import check as check_io
from robogym_ray.envs.io_descriptors import load as io_descriptors_load
from robogym_ray.errors import ConfigError
from robogym_ray.learner.behaviour import from_env_action
from robogym_ray.onnx_policy import OnnxPolicy
from robogym_ray.text import clip_text, reason

SUFFIXES = (".pt", ".onnx")
RSL_RL_LAYOUT = (
    "TorchScript of a module whose forward(obs [1, N]) returns actions [1, M], with its actor's "
    "Linear layers as parameters actor.<i>.weight in order (the first [H, N], the last [M, H]), "
    "an observation normaliser in front optional; `robogym-ray isaac-lab-sample DIR` writes one"
)
"""What rsl_rl's ``policy.pt`` is, as the refusal of another TorchScript file says."""


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

    def unit_policy(self, env: Any, ema_alpha: float = 1.0) -> IsaacRosDecoder:
        """This policy behind Isaac ROS's decoder, for the greedy-episode loop (actions in
        [-1, 1]). With IO descriptors, first the check against ``env`` (ConfigError on a
        mismatch, before any action)."""
        if self.io is None:
            return IsaacRosDecoder(self, env, None, ema_alpha)
        env_id = env.spec.id if env.spec is not None else type(env.unwrapped).__name__
        declare = getattr(env.unwrapped, "isaac_io", None)
        if declare is None:
            raise ConfigError(
                f"{env_id} declares no Isaac Lab observation and action terms: --io-descriptors "
                "works with the IsaacReachUR10 and IsaacDeployReachUR10e ids"
            )
        contract = declare()
        return IsaacRosDecoder(
            self, env, (check_io(self.io, contract, env_id), contract), ema_alpha
        )


class IsaacRosDecoder:
    """Isaac ROS's action decoder in front of the greedy-episode loop (the module docstring):
    clamp, EMA, the IO descriptors' action term, back onto the loop's [-1, 1].

    Args:
        policy: raw observations -> raw actions.
        env: the env (its action bounds).
        io: the checked action map and the env's IO contract, or None (the env's own map).
        ema_alpha: the filter's weight of the newest action, in (0, 1]; 1.0 is none.
    """

    def __init__(
        self, policy: Any, env: Any, io: tuple[ActionMap, IOContract] | None, ema_alpha: float
    ) -> None:
        if not 0.0 < ema_alpha <= 1.0:
            raise ConfigError(f"ema_alpha must be in (0, 1], got {ema_alpha!r}")
        self.policy, self.io, self.alpha = policy, io, float(ema_alpha)
        self.low = env.action_space.low.astype(np.float64)
        self.high = env.action_space.high.astype(np.float64)
        self.last = np.zeros_like(self.low)

    def reset(self) -> None:
        """A new episode: the filter starts from zero (the greedy loop calls this)."""
        self.last = np.zeros_like(self.low)

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        action = np.clip(self.policy(obs), self.low, self.high)
        if self.alpha < 1.0:
            action = self.alpha * action + (1.0 - self.alpha) * self.last
        self.last = action
        if self.io is not None:  # the file's term, then back into the env's action units
            action_map, contract = self.io
            offset = np.asarray(contract.action.offset, dtype=np.float64)
            action = (action_map.processed(action) - offset) / contract.action.scale
        return from_env_action(action, self.low, self.high)


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
        found = [name for name, _ in module.named_parameters()]
        raise ConfigError(
            f"{path}: a TorchScript file without actor.<i>.weight layers (its parameters: "
            f"{clip_text(', '.join(found) or 'none', 120)}) - not an rsl_rl export (expected: "
            f"{RSL_RL_LAYOUT})"
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
