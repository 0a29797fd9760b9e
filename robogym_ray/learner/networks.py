"""Policy and distributional critic networks for D4PG."""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import torch
from torch import nn

from robogym_ray.errors import ConfigError

if TYPE_CHECKING:
    from robogym_ray.learner.config import D4PGConfig


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
    ``_high``), or around the action that holds an arm still (``D4PGConfig.hold_residual``).

    Buffers: the part's centre and half-width on the [-1, 1] scale of the whole Box, and for
    the hold, the observation entry each action dimension follows and its gain, so that the
    centre is ``box_center + hold_gain * obs[hold_index]``. The whole Box (centre 0,
    half-width 1, gain 0) until :meth:`set_action_box` or :meth:`set_hold`.

    They are buffers, so state dicts carry them to the workers, the evaluator, checkpoints and
    exports. Weights saved before them have none: they load as the whole Box.
    """

    box_center: torch.Tensor
    box_half: torch.Tensor
    hold_index: torch.Tensor
    hold_gain: torch.Tensor
    BOX_KEYS = ("box_center", "box_half", "hold_index", "hold_gain")

    def _init_box(self, act_dim: int) -> None:
        self.register_buffer("box_center", torch.zeros(act_dim))
        self.register_buffer("box_half", torch.ones(act_dim))
        self.register_buffer("hold_index", torch.zeros(act_dim, dtype=torch.long))
        self.register_buffer("hold_gain", torch.zeros(act_dim))

    def set_action_box(self, low: Sequence[float], high: Sequence[float]) -> None:
        """Work in ``[low, high]`` (per dimension, on the whole Box's [-1, 1] scale); empty
        sequences keep the whole Box."""
        if not low and not high:
            return
        lo, hi = (torch.as_tensor(v, dtype=torch.float32) for v in (low, high))
        self._check_dims(f"an action box of {len(low)} and {len(high)} bounds", len(low), len(high))
        self.box_center.copy_((hi + lo) / 2)
        self.box_half.copy_((hi - lo) / 2)

    def set_hold(
        self,
        index: Sequence[int],
        gain: Sequence[float],
        offset: Sequence[float],
        half: Sequence[float],
    ) -> None:
        """Work around ``offset + gain * obs[index]`` (the action that holds still), within
        ``half`` of it (per dimension, on the whole Box's [-1, 1] scale); empty sequences keep
        the whole Box."""
        if not index:
            return
        self._check_dims(
            f"a hold of {len(index)} dimensions", len(index), len(gain), len(offset), len(half)
        )
        self.hold_index.copy_(torch.as_tensor(index, dtype=torch.long))
        self.hold_gain.copy_(torch.as_tensor(gain, dtype=torch.float32))
        self.box_center.copy_(torch.as_tensor(offset, dtype=torch.float32))
        self.box_half.copy_(torch.as_tensor(half, dtype=torch.float32))

    def _check_dims(self, what: str, *lengths: int) -> None:
        if any(n != self.box_center.numel() for n in lengths):
            raise ValueError(f"{what} for {self.box_center.numel()} action dimensions")

    def center(self, obs: torch.Tensor) -> torch.Tensor:
        """The centre of the part of the Box the net works in, for ``obs`` (B x obs_dim)."""
        return self.box_center + self.hold_gain * obs[..., self.hold_index]

    def _load_from_state_dict(self, state_dict: Any, prefix: str, *args: Any) -> None:
        # torch hands each module a copy of the state dict: filling it in here changes no
        # caller's dict, and works for a net loaded inside another module too.
        # Weights from before the hold had none, whatever this net's config asks: no hold
        # (a loaded net keeps the part it was trained in, as it keeps its box).
        if prefix + "box_center" in state_dict:
            for name in ("hold_index", "hold_gain"):
                state_dict.setdefault(prefix + name, torch.zeros_like(getattr(self, name)))
        for name in self.BOX_KEYS:
            state_dict.setdefault(prefix + name, getattr(self, name))
        super()._load_from_state_dict(state_dict, prefix, *args)


class Policy(ActionBox):
    """Deterministic policy ``obs -> centre + half-width * tanh(...)``: actions in [-1, 1], in
    its action box, or around holding still, when it has one."""

    def __init__(
        self, obs_dim: int, act_dim: int, hidden: Sequence[int], layer_norm: bool = False
    ) -> None:
        super().__init__()
        self.net = mlp(obs_dim, hidden, act_dim, layer_norm)
        self._init_box(act_dim)

    def forward(self, obs: torch.Tensor) -> torch.Tensor:
        # The clamp matters only around a hold, whose centre moves with the observation.
        action = self.center(obs) + self.box_half * torch.tanh(self.net(obs))
        return torch.clamp(action, -1.0, 1.0)


class DistributionalCritic(ActionBox):
    """``(obs, action) -> logits`` over a fixed support of ``num_atoms`` atoms; the action is
    read on its action box's own [-1, 1] scale (around a hold: as the step from holding
    still)."""

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
        self._init_box(act_dim)

    def forward(self, obs: torch.Tensor, action: torch.Tensor) -> torch.Tensor:
        scaled = (action - self.center(obs)) / self.box_half
        return self.net(torch.cat([obs, scaled], dim=-1))


def set_action_part(net: ActionBox, config: D4PGConfig) -> None:
    """Give ``net`` the part of the action Box that ``config`` names: its action box, or its
    hold (a ConfigError for a hold the trainer has not filled in from the task's env, a
    ValueError for a part of another number of dimensions)."""
    if config.hold_residual > 0 and not config.hold_index:
        raise ConfigError(
            "hold_residual needs hold_index, hold_gain and hold_offset, which the trainer "
            "fills in from the task's env (its hold_map)"
        )
    net.set_action_box(config.action_box_low, config.action_box_high)
    net.set_hold(config.hold_index, config.hold_gain, config.hold_offset, config.hold_half)
