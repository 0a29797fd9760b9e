"""Policy and distributional critic networks for D4PG, and the observation normaliser both
may carry (``obs_norm``)."""

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


class ObsNormalizer(nn.Module):
    """``(obs - mean) / (std + EPS)`` clipped to ``+-CLIP``, from running statistics.

    The statistics are buffers (count, mean, sum of squared deviations, float64), so they travel
    with the network's state dict: to the workers with the weights, into checkpoints, policy
    files and ONNX exports. Only the learner calls :meth:`update`, with the observations it is
    given; before the first update the statistics are mean 0, std 1 (``obs / 1.01``, clipped).
    ``std + EPS`` is rsl_rl's ``EmpiricalNormalization``'s: an observation that never varies (a
    fixed joint) becomes 0 instead of noise divided by zero. The clip is OpenAI baselines' HER's
    (``norm_clip``): an outlier cannot swamp the first layer.
    """

    EPS = 1e-2
    CLIP = 5.0

    def __init__(self, dim: int) -> None:
        super().__init__()
        self.register_buffer("count", torch.zeros((), dtype=torch.float64))
        self.register_buffer("mean", torch.zeros(dim, dtype=torch.float64))
        self.register_buffer("m2", torch.zeros(dim, dtype=torch.float64))

    @torch.no_grad()
    def update(self, obs: torch.Tensor) -> None:
        """Fold a batch (B x dim) into the statistics (Chan et al.'s parallel update: any split
        of the data into batches gives the same statistics up to float64 rounding)."""
        x = obs.to(self.mean.device, torch.float64).reshape(-1, self.mean.numel())
        n = x.shape[0]
        if n == 0:
            return
        batch_mean = x.mean(0)
        delta = batch_mean - self.mean
        total = self.count + n
        self.mean.add_(delta * (n / total))
        self.m2.add_(((x - batch_mean) ** 2).sum(0) + delta**2 * (self.count * n / total))
        self.count.copy_(total)

    def std(self) -> torch.Tensor:
        """The running standard deviation (float64); 1 before any observation."""
        var = torch.where(self.count > 0, self.m2 / self.count.clamp_min(1.0), 1.0)
        return var.sqrt()

    def forward(self, obs: torch.Tensor) -> torch.Tensor:
        mean, std = self.mean.to(obs.dtype), self.std().to(obs.dtype)
        return ((obs - mean) / (std + self.EPS)).clamp(-self.CLIP, self.CLIP)


class Policy(nn.Module):
    """Deterministic policy ``obs -> tanh(...)`` with actions in [-1, 1]; with ``obs_norm``
    the observations pass through an :class:`ObsNormalizer` (``norm``) first."""

    def __init__(
        self,
        obs_dim: int,
        act_dim: int,
        hidden: Sequence[int],
        layer_norm: bool = False,
        obs_norm: bool = False,
    ) -> None:
        super().__init__()
        self.norm = ObsNormalizer(obs_dim) if obs_norm else None
        self.net = mlp(obs_dim, hidden, act_dim, layer_norm)

    def forward(self, obs: torch.Tensor) -> torch.Tensor:
        if self.norm is not None:
            obs = self.norm(obs)
        return torch.tanh(self.net(obs))


class DistributionalCritic(nn.Module):
    """``(obs, action) -> logits`` over a fixed support of ``num_atoms`` atoms; ``obs_norm`` as
    the policy's (the learner keeps both normalisers equal)."""

    def __init__(
        self,
        obs_dim: int,
        act_dim: int,
        hidden: Sequence[int],
        num_atoms: int,
        layer_norm: bool = False,
        obs_norm: bool = False,
    ) -> None:
        super().__init__()
        self.norm = ObsNormalizer(obs_dim) if obs_norm else None
        self.net = mlp(obs_dim + act_dim, hidden, num_atoms, layer_norm)

    def forward(self, obs: torch.Tensor, action: torch.Tensor) -> torch.Tensor:
        if self.norm is not None:
            obs = self.norm(obs)
        return self.net(torch.cat([obs, action], dim=-1))
