"""The whole learner step (``whole_step``, learner/whole_step.py) on the CPU the tests have: the
same code a GPU captures in one CUDA graph, run eagerly. It must take the host-stepped loop's
steps exactly when given the same uniform draws (the one thing it changes is where the draws
come from), go on after a restore as if never stopped, and be refused where it cannot run."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from robogym_ray.errors import ConfigError
from robogym_ray.learner.learner import D4PGLearner
from tests.learner.conftest import (
    ACT,
    OBS,
    assert_same,
    filled_learner,
    net_params,
    small_config,
    transitions,
)

SCHEDULES = dict(lr_decay_start=2, lr_decay_steps=5, lr_final_scale=0.3,
                 importance_beta_steps=9, policy_average_tau=0.1)  # fmt: skip
"""Every schedule moving within the test's steps: a constant baked into a graph would show."""


def _filled(**kw: object) -> D4PGLearner:
    return filled_learner(**{**SCHEDULES, **kw})


class _TorchDraws:
    """A NumPy-generator stand-in for the host path's replay: torch's draws from ``seed``."""

    def __init__(self, seed: int) -> None:
        self.generator = torch.Generator().manual_seed(seed)

    def random(self, n: int) -> np.ndarray:
        return torch.rand(n, dtype=torch.float64, generator=self.generator).numpy()


@pytest.mark.parametrize("sgd_steps", [1, 3])
def test_given_the_same_draws_the_whole_step_takes_the_host_paths_steps(sgd_steps: int) -> None:
    """Hard target copies every 3 steps, a learning-rate decay, the importance exponent's ramp,
    a policy average and priorities written back: after 11 steps in calls of 4, 2 and 5 (blocks
    of 3 cut short at a call's end), the networks, targets, average and priorities equal the
    host-stepped loop's bit for bit, and so do the metrics."""
    whole = _filled(whole_step="on", sgd_steps_per_sample=sgd_steps)
    host = _filled(replay_device="learner", sgd_steps_per_sample=sgd_steps)
    assert whole.device_loop is not None and host.device_loop is None
    assert isinstance(whole.policy_opt.param_groups[0]["lr"], torch.Tensor)
    drawn = _TorchDraws(5).generator
    whole.device_loop.draw = lambda n: torch.rand(n, dtype=torch.float64, generator=drawn)
    host.replay.rng = _TorchDraws(5)
    for steps in (4, 2, 5):
        a, b = whole.run(steps), host.run(steps)
        assert a == pytest.approx(b, rel=1e-6, abs=0)
        new = transitions(20, seed=steps)  # inserts between calls move the fill level and the max
        whole.add(new)
        host.add(new)
    assert whole.num_steps == host.num_steps == 11 == int(whole.device_loop.step)
    assert_same(whole, host)
    for x, y in zip(whole.policy_average.parameters(), host.policy_average.parameters(),
                    strict=True):  # fmt: skip
        torch.testing.assert_close(x, y, atol=0, rtol=0)
    assert whole.replay.max_priority == host.replay.max_priority
    rate = whole.critic_opt.param_groups[0]["lr"]
    assert float(rate) == pytest.approx(host.critic_opt.param_groups[0]["lr"], rel=1e-7)


def test_its_own_draws_are_reproducible_and_spread_over_the_replay() -> None:
    """It draws from torch's default generator of its device, which the learner seeds (the
    learner's process draws nothing else): one seed, one run."""
    a = _filled(whole_step="on")
    seen = []
    sample = a.replay.sample_drawn

    def record(draws, beta):  # noqa: ANN001, ANN202
        out = sample(draws, beta)
        seen.append(out[1].clone())
        return out

    a.replay.sample_drawn = record
    first = a.run(6)
    b = _filled(whole_step="on")
    assert b.run(6) == first
    assert_same(a, b)
    idx = torch.cat(seen)
    assert idx.min() >= 0 and idx.max() < len(a.replay)
    assert idx.unique().numel() > 0.5 * idx.numel()  # stratified: not one slot over and over


def test_a_restored_whole_step_goes_on_as_if_never_stopped(tmp_path) -> None:  # noqa: ANN001
    """Its draws, counter and tensor learning rates survive a checkpoint: 6 steps, a restore
    into a new learner, 7 more equal 13 uninterrupted steps."""
    kw = dict(whole_step="on", sgd_steps_per_sample=2)
    first = _filled(**kw)
    first.run(6)
    first.save(tmp_path / "learner.pt", include_replay=True)
    went_on = first.run(7)
    resumed = D4PGLearner(small_config(**{**SCHEDULES, **kw}), OBS, ACT, seed=99)
    resumed.restore(tmp_path / "learner.pt")
    assert int(resumed.device_loop.step) == resumed.num_steps == 6
    assert isinstance(resumed.critic_opt.param_groups[0]["lr"], torch.Tensor)
    assert resumed.run(7) == went_on
    for x, y in zip(net_params(first), net_params(resumed), strict=True):
        torch.testing.assert_close(x, y, atol=0, rtol=0)


def test_auto_is_the_host_loop_on_a_cpu() -> None:
    learner = _filled(whole_step="auto")
    assert learner.device_loop is None and learner.replay.backend.on_host


@pytest.mark.parametrize(
    ("kw", "why"),
    [({"whole_step": "graph"}, "'on', 'off' or 'auto'"),
     ({"whole_step": "on", "compile": "default"}, "with compile ''"),
     ({"whole_step": "on", "replay_device": "host"}, "the replay on the learner's device")],
)  # fmt: skip
def test_settings_it_cannot_run_with_are_refused(kw: dict, why: str) -> None:
    with pytest.raises(ConfigError, match="D4PGConfig.whole_step=") as refused:
        small_config(**kw)
    assert why in str(refused.value)


@pytest.mark.skipif(not torch.cuda.is_available(), reason="a CUDA graph needs a GPU")
def test_on_cuda_the_captured_graph_takes_the_host_paths_steps() -> None:
    """On a GPU (run on the node; CI has none): the whole step warms up, captures one graph and
    replays it; fed the host path's draws through one device buffer that the graph reads, its
    11 steps (schedules moving, hard copies, priorities, inserts between calls) match the host
    loop's to float32 round-off (atomics in the backward make a GPU's sums order-dependent)."""
    whole = _filled(whole_step="on", device="cuda")
    host = _filled(replay_device="learner", device="cuda")
    draws = torch.zeros(whole.config.batch_size, dtype=torch.float64, device="cuda")
    whole.device_loop.draw = lambda n: draws  # the graph keeps reading this buffer
    source = _TorchDraws(5)
    host.replay.rng = _TorchDraws(5)
    for steps in (4, 2, 5):
        for _ in range(steps):
            draws.copy_(torch.from_numpy(source.random(len(draws))))
            a, b = whole.run(1), host.run(1)
        assert a == pytest.approx(b, rel=1e-4, abs=1e-6)
        new = transitions(20, seed=steps)
        whole.add(new)
        host.add(new)
    loop = whole.device_loop
    assert loop.graph is not None and whole.num_steps == int(loop.step) == 11
    for x, y in zip(net_params(whole), net_params(host), strict=True):
        torch.testing.assert_close(x, y, rtol=1e-4, atol=1e-5)
