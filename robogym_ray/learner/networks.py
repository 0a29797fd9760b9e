"""Policy and distributional critic networks for D4PG."""

from __future__ import annotations

from collections.abc import Sequence

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


class Policy(nn.Module):
    """Deterministic policy ``obs -> tanh(...)`` with actions in [-1, 1]."""

    def __init__(
        self, obs_dim: int, act_dim: int, hidden: Sequence[int], layer_norm: bool = False
    ) -> None:
        super().__init__()
        self.net = mlp(obs_dim, hidden, act_dim, layer_norm)

    def forward(self, obs: torch.Tensor) -> torch.Tensor:
        return torch.tanh(self.net(obs))


class DistributionalCritic(nn.Module):
    """``(obs, action) -> logits`` over a fixed support of ``num_atoms`` atoms."""

    def __init__(
        self,
        obs_dim: int,
        act_dim: int,
        hidden: Sequence[int],
        num_atoms: int,
        layer_norm: bool = False,
    ) -> None:
        super().__init__()
        self.net = mlp(obs_dim + act_dim, hidden, num_atoms, layer_norm)

    def forward(self, obs: torch.Tensor, action: torch.Tensor) -> torch.Tensor:
        return self.net(torch.cat([obs, action], dim=-1))
