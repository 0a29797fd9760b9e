"""n-step returns on hand-worked episodes."""

from __future__ import annotations

import numpy as np
import pytest

from robogym_ray.errors import ConfigError
from robogym_ray.learner.nstep import NStepAccumulator, stack_transitions


def _run(acc: NStepAccumulator, rewards: list[float], end: str) -> list:
    """Feed an episode with obs s_t = [t]; end is 'terminated', 'truncated' or 'none'."""
    out = []
    for t, r in enumerate(rewards):
        last = t == len(rewards) - 1
        out += acc.push(
            np.array([t]),
            np.array([0.1 * t]),
            r,
            np.array([t + 1]),
            terminated=last and end == "terminated",
            truncated=last and end == "truncated",
        )
    return out


def test_full_windows_then_truncation_bootstraps_with_shortened_discounts() -> None:
    acc = NStepAccumulator(n_step=3, discount=0.5)
    out = _run(acc, [1.0, 2.0, 3.0, 4.0], end="truncated")
    assert [int(t.obs[0]) for t in out] == [0, 1, 2, 3]
    # R_0 = 1 + .5*2 + .25*3, R_1 = 2 + .5*3 + .25*4, then windows shortened by the end.
    assert [t.reward for t in out] == pytest.approx([2.75, 4.5, 5.0, 4.0])
    assert [t.discount for t in out] == pytest.approx([0.125, 0.125, 0.25, 0.5])
    assert [int(t.next_obs[0]) for t in out] == [3, 4, 4, 4]
    assert len(acc) == 0


def test_termination_does_not_bootstrap() -> None:
    acc = NStepAccumulator(n_step=3, discount=0.5)
    out = _run(acc, [1.0, 2.0, 3.0, 4.0], end="terminated")
    assert [t.reward for t in out] == pytest.approx([2.75, 4.5, 5.0, 4.0])
    # The first window ends before the terminal step, so it still bootstraps from s_3.
    assert [t.discount for t in out] == pytest.approx([0.125, 0.0, 0.0, 0.0])


def test_episode_shorter_than_n() -> None:
    acc = NStepAccumulator(n_step=5, discount=0.9)
    out = _run(acc, [1.0, 1.0], end="terminated")
    assert [t.reward for t in out] == pytest.approx([1.9, 1.0])
    assert [t.discount for t in out] == [0.0, 0.0]
    out = _run(acc, [1.0, 1.0], end="truncated")
    assert [t.discount for t in out] == pytest.approx([0.81, 0.9])


def test_n_equal_one_is_plain_one_step() -> None:
    acc = NStepAccumulator(n_step=1, discount=0.99)
    out = _run(acc, [3.0, 4.0], end="none")
    # pytest 9 refuses nested structures in approx: compare each field on its own, as strictly.
    assert [t.reward for t in out] == pytest.approx([3.0, 4.0])
    assert [t.discount for t in out] == pytest.approx([0.99, 0.99])


def test_drop_discards_unfinished_window_after_a_crash() -> None:
    acc = NStepAccumulator(n_step=3, discount=0.5)
    assert _run(acc, [1.0, 2.0], end="none") == []
    assert acc.drop() == 2 and len(acc) == 0
    out = _run(acc, [10.0, 20.0, 30.0], end="none")
    # Nothing from before the crash leaks into the new episode's returns.
    assert len(out) == 1 and out[0].reward == pytest.approx(10 + 10 + 7.5)
    acc.reset()
    assert len(acc) == 0


def test_stack_and_validation() -> None:
    acc = NStepAccumulator(n_step=2, discount=0.5)
    batch = stack_transitions(_run(acc, [1.0, 2.0, 3.0], end="truncated"))
    assert batch["obs"].shape == (3, 1) and batch["reward"].dtype == np.float32
    with pytest.raises(ConfigError):
        NStepAccumulator(n_step=0, discount=0.5)
