"""Categorical (C51-style) value-distribution math for the D4PG critic, in PyTorch."""

from __future__ import annotations

import torch


def make_support(
    v_min: float, v_max: float, num_atoms: int, device: torch.device | str = "cpu"
) -> torch.Tensor:
    """Evenly spaced atoms ``z_0 = v_min, ..., z_{K-1} = v_max``."""
    return torch.linspace(v_min, v_max, num_atoms, device=device)


def categorical_projection(
    target_probs: torch.Tensor,
    rewards: torch.Tensor,
    discounts: torch.Tensor,
    support: torch.Tensor,
) -> torch.Tensor:
    """Project the distribution of ``r + discount * Z`` onto the fixed ``support``.

    Each shifted atom ``r + d * z_i`` (clipped to the support's range) hands its probability to
    its two neighbouring support atoms in proportion to closeness (the L2 / triangular-kernel
    projection of Bellemare et al. 2017), so mass is conserved exactly. A zero discount
    (termination) collapses the whole distribution onto ``r``.

    Args:
        target_probs: (B, K) probabilities of the target distribution over ``support``.
        rewards: (B,) n-step discounted reward sums.
        discounts: (B,) bootstrap discounts ``gamma**n`` (0 where the episode terminated).
        support: (K,) evenly spaced atoms.

    Returns:
        (B, K) projected probabilities.
    """
    num_atoms = support.shape[0]
    v_min, v_max = support[0], support[-1]
    delta = (v_max - v_min) / (num_atoms - 1)
    shifted = rewards[:, None] + discounts[:, None] * support[None, :]
    # Fractional index of every shifted atom on the support grid, in [0, K-1].
    pos = (shifted.clamp(v_min, v_max) - v_min) / delta
    # Taking lower = floor clamped to K-2 (not ceil/floor pairs) keeps the exact-hit case from
    # dropping mass: an atom landing on z_{K-1} gives weight 1 to upper = K-1.
    lower = pos.floor().clamp(max=num_atoms - 2)
    upper_w = pos - lower
    lower_idx = lower.long()
    out = torch.zeros_like(target_probs)
    out.scatter_add_(1, lower_idx, target_probs * (1.0 - upper_w))
    out.scatter_add_(1, lower_idx + 1, target_probs * upper_w)
    return out


def expected_value(logits: torch.Tensor, support: torch.Tensor) -> torch.Tensor:
    """Mean of the categorical distribution given by ``logits`` (B, K) -> (B,)."""
    return torch.softmax(logits, dim=-1) @ support


def categorical_cross_entropy(logits: torch.Tensor, target_probs: torch.Tensor) -> torch.Tensor:
    """Per-sample cross-entropy ``-sum_k p_k log q_k`` between target and online logits."""
    return -(target_probs * torch.log_softmax(logits, dim=-1)).sum(dim=-1)
