"""``robogym-ray isaac-lab-sample DIR``: an untrained policy in the layout of Isaac Lab's rsl_rl
export, to try docs/isaac-lab.md's steps without Isaac Lab.

``DIR/policy.pt`` and ``DIR/policy.onnx`` are what ``play.py`` writes (``RSL_RL_LAYOUT`` in
``robogym_ray.isaac_lab``): a module whose ``forward(obs)`` is ``actor(normalizer(obs))``, the
actor an MLP (Linear, ELU, Linear, ELU, Linear: parameters ``actor.0`` ... ``actor.4``) behind
rsl_rl's empirical observation normaliser, scripted with ``torch.jit.script``; the same network
as ONNX with input ``obs`` ``[1, N]`` and output ``actions`` ``[1, M]``, opset 11. The weights
are random (seeded): the policy moves the robot, it does not reach the target.
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import sys
from pathlib import Path

import torch
from torch import nn

from robogym_ray.config import check_dir_path
from robogym_ray.errors import ConfigError

DEFAULT_ENV_ID = "RoboGymRay/IsaacReachUR10Sim-v0"
HIDDEN = 64
ISAAC_LAB_OPSET = 11
"""The ONNX opset ``play.py`` exports with."""
FILES = ("policy.pt", "policy.onnx")


class EmpiricalNormalization(nn.Module):
    """rsl_rl's observation normaliser as it sits in the exported module (eval mode)."""

    def __init__(self, size: int, eps: float = 1e-2) -> None:
        super().__init__()
        self.eps = eps
        self.register_buffer("_mean", torch.zeros(size).unsqueeze(0))
        self.register_buffer("_var", torch.ones(size).unsqueeze(0))
        self.register_buffer("_std", torch.ones(size).unsqueeze(0))
        self.register_buffer("count", torch.tensor(0, dtype=torch.long))

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return (x - self._mean) / (self._std + self.eps)


class PolicyExporter(nn.Module):
    """The shape of Isaac Lab's ``_TorchPolicyExporter``: ``actor(normalizer(obs))``, with a
    normaliser whose statistics are drawn too, so that it is not the identity."""

    def __init__(self, obs_dim: int, act_dim: int, seed: int = 0) -> None:
        super().__init__()
        with torch.random.fork_rng():  # seeded without touching the caller's generator
            torch.manual_seed(seed)
            self.actor = nn.Sequential(
                nn.Linear(obs_dim, HIDDEN),
                nn.ELU(),
                nn.Linear(HIDDEN, HIDDEN),
                nn.ELU(),
                nn.Linear(HIDDEN, act_dim),
            )
            self.normalizer = EmpiricalNormalization(obs_dim)
            self.normalizer._mean.uniform_(-0.5, 0.5)
            self.normalizer._std.uniform_(0.5, 2.0)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.actor(self.normalizer(x))

    @torch.jit.export
    def reset(self) -> None:
        """rsl_rl's exporters have it (a recurrent one clears its hidden state)."""


def write_sample(
    folder: str | Path, obs_dim: int, act_dim: int, seed: int = 0, onnx: bool = True
) -> tuple[Path, Path | None, nn.Module]:
    """Write ``folder/policy.pt`` and, with ``onnx``, ``folder/policy.onnx`` (it needs the
    ``onnx`` package); returns their paths and the module both hold (in eval mode)."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    module = PolicyExporter(obs_dim, act_dim, seed).eval()
    torch.jit.script(module).save(str(folder / "policy.pt"))
    if not onnx:
        return folder / "policy.pt", None, module
    from robogym_ray.onnx_policy import write_onnx

    write_onnx(module, obs_dim, folder / "policy.onnx", any_batch=False, opset=ISAAC_LAB_OPSET)
    return folder / "policy.pt", folder / "policy.onnx", module


# -- CLI: robogym-ray isaac-lab-sample ---------------------------------------------------------
def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "folder",
        help="Folder to write policy.pt and policy.onnx into (made if missing); policy files "
        "already there are not overwritten.",
    )
    parser.add_argument(
        "--env-id",
        default=DEFAULT_ENV_ID,
        help=f"The env whose observation and action sizes the policy takes (default: "
        f"{DEFAULT_ENV_ID}).",
    )
    parser.add_argument("--seed", type=int, default=0, help="Seed of the weights (default: 0).")


def run(args: argparse.Namespace) -> int:
    from robogym_ray.export import env_spaces

    folder = Path(args.folder)
    check_dir_path(folder, "isaac-lab-sample FOLDER")
    taken = [name for name in FILES if (folder / name).exists()]
    if taken:
        raise ConfigError(
            f"isaac-lab-sample FOLDER {folder}: {' and '.join(taken)} already there (an export "
            "of yours?); give a new folder"
        )
    obs_space, act_space = env_spaces(args.env_id)
    obs_dim, act_dim = int(obs_space.shape[0]), int(act_space.shape[0])
    onnx = importlib.util.find_spec("onnx") is not None
    pt, onnx_path, _ = write_sample(folder, obs_dim, act_dim, args.seed, onnx)
    if not onnx:
        print("note: policy.onnx needs the onnx package: pip install -e '.[onnx]'", file=sys.stderr)
    print(json.dumps({
        "policy_pt": str(pt), "policy_onnx": str(onnx_path) if onnx_path else None,
        "env_id": args.env_id, "obs_dim": obs_dim, "act_dim": act_dim, "trained": False,
    }))  # fmt: skip
    return 0
