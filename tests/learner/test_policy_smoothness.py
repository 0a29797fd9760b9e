"""The policy's smoothness term (``policy_smoothness``): what it adds to the DPG loss, which
windows it reads, and that it makes the policy change less across them."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch

from robogym_ray.errors import ConfigError
from robogym_ray.learner.learner import D4PGLearner
from tests.learner.conftest import ACT, OBS, filled_learner, small_config, transitions


def _window_change(learner: D4PGLearner, batch: dict[str, np.ndarray]) -> float:
    """The policy's mean squared change from each obs to its window's next obs."""
    with torch.no_grad():
        now = learner.policy(torch.as_tensor(batch["obs"]))
        later = learner.policy(torch.as_tensor(batch["next_obs"]))
    return float((now - later).square().sum(-1).mean())


def test_the_loss_adds_the_weighted_change_to_dpg_and_reports_both() -> None:
    off = filled_learner().step()
    assert off["policy_change"] == 0.0
    assert off["policy_loss"] == pytest.approx(-off["mean_q"], rel=1e-6)
    on = filled_learner(policy_smoothness=2.5).step()
    assert on["policy_change"] > 0 and math.isfinite(on["policy_change"])
    expected = -on["mean_q"] + 2.5 * on["policy_change"]
    assert on["policy_loss"] == pytest.approx(expected, rel=1e-5, abs=1e-6)


def test_a_window_cut_by_the_episode_end_is_not_compared() -> None:
    learner = D4PGLearner(small_config(policy_smoothness=1.0), OBS, ACT, seed=0)
    ended = transitions(100)
    ended["discount"][:] = 0.0
    learner.add(ended)
    assert learner.step()["policy_change"] == 0.0


def test_the_term_makes_the_policy_change_less_across_the_windows() -> None:
    data = transitions(300, seed=3)
    data["discount"][:] = 0.95
    changes = {}
    for weight in (0.0, 50.0):
        learner = D4PGLearner(small_config(policy_smoothness=weight), OBS, ACT, seed=0)
        learner.add(data)
        learner.run(100)
        changes[weight] = _window_change(learner, data)
    assert changes[50.0] < 0.5 * changes[0.0], changes


@pytest.mark.parametrize("bad", [-0.1, float("nan"), float("inf")])
def test_a_weight_that_is_negative_or_not_finite_is_refused(bad: float) -> None:
    with pytest.raises(ConfigError, match="policy_smoothness"):
        small_config(policy_smoothness=bad)
