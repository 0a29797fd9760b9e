"""Policy and distributional critic networks for D4PG."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import torch
from torch import nn


def mlp(
    in_dim: int, hidden: Sequence[int], out_dim: int, layer_norm: bool = False
) -> nn.Sequential:
    """Linear(-LayerNorm)-ReLU stack followed by a linear output layer."""
    layers: list[nn.Module] = []
    for width in hidden:
        layers.append(nn.Linear(in_dim, width))
        if layer_norm:
            layers.append(nn.LayerNorm(width))
        layers.append(nn.ReLU())
        in_dim = width
    layers.append(nn.Linear(in_dim, out_dim))
    return nn.Sequential(*layers)


class ActionBox(nn.Module):
    """A net that works in a part of the env's action Box (``D4PGConfig.action_box_low`` /
    ``_high``): two buffers, the box's centre and half-width on the [-1, 1] scale of the whole
    Box; the whole Box (centre 0, half-width 1) until :meth:`set_action_box`.

    They are buffers, so state dicts carry them to the workers, the evaluator, checkpoints and
    exports. Weights saved before the box existed have none: they load as the whole Box.
    """

    box_center: torch.Tensor
    box_half: torch.Tensor
    BOX_KEYS = ("box_center", "box_half")

    def _init_box(self, act_dim: int) -> None:
        self.register_buffer("box_center", torch.zeros(act_dim))
        self.register_buffer("box_half", torch.ones(act_dim))

    def set_action_box(self, low: Sequence[float], high: Sequence[float]) -> None:
        """Work in ``[low, high]`` (per dimension, on the whole Box's [-1, 1] scale); empty
        sequences keep the whole Box."""
        if not low and not high:
            return
        lo, hi = (torch.as_tensor(v, dtype=torch.float32) for v in (low, high))
        if lo.shape != self.box_center.shape or hi.shape != lo.shape:
            raise ValueError(
                f"an action box of {len(low)} and {len(high)} bounds for "
                f"{self.box_center.numel()} action dimensions"
            )
        self.box_center.copy_((hi + lo) / 2)
        self.box_half.copy_((hi - lo) / 2)

    def _load_from_state_dict(self, state_dict: Any, prefix: str, *args: Any) -> None:
        # torch hands each module a copy of the state dict: filling it in here changes no
        # caller's dict, and works for a net loaded inside another module too.
        for name in self.BOX_KEYS:
            state_dict.setdefault(prefix + name, getattr(self, name))
        super()._load_from_state_dict(state_dict, prefix, *args)


class Policy(ActionBox):
    """Deterministic policy ``obs -> centre + half-width * tanh(...)``: actions in [-1, 1], in
    its action box when it has one."""

    def __init__(
        self, obs_dim: int, act_dim: int, hidden: Sequence[int], layer_norm: bool = False
    ) -> None:
        super().__init__()
        self.net = mlp(obs_dim, hidden, act_dim, layer_norm)
        self._init_box(act_dim)

    def forward(self, obs: torch.Tensor) -> torch.Tensor:
        return self.box_center + self.box_half * torch.tanh(self.net(obs))


class DistributionalCritic(ActionBox):
    """``(obs, action) -> logits`` over a fixed support of ``num_atoms`` atoms; the action is
    read on its action box's own [-1, 1] scale, and with ``features`` (``learner/features.py``)
    the net also reads what they compute from the observation and the action."""

    def __init__(
        self,
        obs_dim: int,
        act_dim: int,
        hidden: Sequence[int],
        num_atoms: int,
        layer_norm: bool = False,
        features: nn.Module | None = None,
    ) -> None:
        super().__init__()
        extra = int(getattr(features, "dim", 0))
        self.net = mlp(obs_dim + act_dim + extra, hidden, num_atoms, layer_norm)
        self._init_box(act_dim)
        self.features = features

    def forward(self, obs: torch.Tensor, action: torch.Tensor) -> torch.Tensor:
        scaled = (action - self.box_center) / self.box_half
        if self.features is None:
            return self.net(torch.cat([obs, scaled], dim=-1))
        return self.net(torch.cat([obs, scaled, self.features(obs, action)], dim=-1))
