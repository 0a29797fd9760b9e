"""Categorical projection against a brute-force loop reference."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from robogym_ray.learner.distributional import (
    categorical_cross_entropy,
    categorical_projection,
    expected_value,
    make_support,
)


def brute_force_projection(
    probs: np.ndarray, rewards: np.ndarray, discounts: np.ndarray, support: np.ndarray
) -> np.ndarray:
    """Triangular-kernel projection written as plain loops (independent of the scatter code)."""
    batch, atoms = probs.shape
    delta = support[1] - support[0]
    out = np.zeros_like(probs, dtype=np.float64)
    for b in range(batch):
        for i in range(atoms):
            tz = np.clip(rewards[b] + discounts[b] * support[i], support[0], support[-1])
            for j in range(atoms):
                out[b, j] += probs[b, i] * max(0.0, 1.0 - abs(tz - support[j]) / delta)
    return out


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_projection_matches_loop_reference_and_conserves_mass(seed: int) -> None:
    rng = np.random.default_rng(seed)
    support = np.linspace(-10.0, 10.0, 11)
    probs = rng.dirichlet(np.ones(11), size=16)
    # Rewards partly outside the support exercise the clipping at both ends.
    rewards = rng.uniform(-15.0, 15.0, 16)
    discounts = rng.choice([0.0, 0.5, 0.9, 1.0], 16)
    got = categorical_projection(
        torch.tensor(probs), torch.tensor(rewards), torch.tensor(discounts), torch.tensor(support)
    ).numpy()
    np.testing.assert_allclose(
        got, brute_force_projection(probs, rewards, discounts, support), atol=1e-10
    )
    np.testing.assert_allclose(got.sum(axis=1), 1.0, atol=1e-12)
    assert (got >= 0).all()


def test_exact_atom_hits_including_the_top_atom_keep_their_mass() -> None:
    support = torch.linspace(0.0, 4.0, 5, dtype=torch.float64)
    probs = torch.full((1, 5), 0.2, dtype=torch.float64)
    got = categorical_projection(probs, torch.tensor([0.0]), torch.tensor([1.0]), support)
    torch.testing.assert_close(got, probs)


def test_termination_collapses_onto_reward() -> None:
    support = torch.linspace(-1.0, 1.0, 5, dtype=torch.float64)  # spacing 0.5
    probs = torch.softmax(torch.randn(1, 5, dtype=torch.float64), -1)
    got = categorical_projection(probs, torch.tensor([0.25]), torch.tensor([0.0]), support)
    torch.testing.assert_close(got, torch.tensor([[0.0, 0.0, 0.5, 0.5, 0.0]], dtype=torch.float64))


def test_expected_value_and_cross_entropy() -> None:
    support = make_support(-1.0, 1.0, 3)
    logits = torch.log(torch.tensor([[0.25, 0.25, 0.5]]))
    assert expected_value(logits, support).item() == pytest.approx(0.25)
    target = torch.tensor([[0.0, 0.0, 1.0]])
    assert categorical_cross_entropy(logits, target).item() == pytest.approx(np.log(2.0))
