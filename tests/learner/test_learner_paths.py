"""The learner's one code path for every device: ``run`` takes exactly the plain D4PG step
written out below, bit for bit; a replay on the learner's device samples what the host replay
does (the same indices; its priorities within a few ulps: numpy and torch may round a power
differently); block sampling, bf16 and torch.compile run on the CPU the tests have."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from torch import nn

from robogym_ray.errors import ConfigError
from robogym_ray.learner.distributional import (
    categorical_cross_entropy,
    categorical_projection,
    expected_value,
)
from robogym_ray.learner.learner import D4PGLearner
from robogym_ray.learner.schedules import importance_beta
from tests.learner.conftest import (
    assert_same,
    filled_learner,
    net_params,
    small_config,
    transitions,
)


def reference_step(learner: D4PGLearner) -> None:
    """One plain D4PG step, written out with torch alone (only the learning-rate schedule and
    the target update are the learner's): one prioritized sample, the critic's and the policy's
    update, priorities to the host, targets."""
    c = learner.config
    beta = importance_beta(c, learner.num_steps)
    learner.set_lr(learner.num_steps)
    batch, idx, weights = learner.replay.sample(c.batch_size, beta)
    b = {k: torch.as_tensor(v) for k, v in batch.items()}
    w = torch.as_tensor(weights)
    with torch.no_grad():
        nxt = learner.target_critic(b["next_obs"], learner.target_policy(b["next_obs"]))
        target = categorical_projection(
            torch.softmax(nxt, -1), b["reward"], b["discount"], learner.support
        )
    per_sample = categorical_cross_entropy(learner.critic(b["obs"], b["action"]), target)
    learner.critic_opt.zero_grad(set_to_none=True)
    (w * per_sample).mean().backward()
    nn.utils.clip_grad_norm_(learner.critic.parameters(), c.max_grad_norm, foreach=True)
    learner.critic_opt.step()
    q = expected_value(learner.critic(b["obs"], learner.policy(b["obs"])), learner.support)
    params = list(learner.policy.parameters())
    for p, g in zip(params, torch.autograd.grad(-q.mean(), params), strict=True):
        p.grad = g
    nn.utils.clip_grad_norm_(params, c.max_grad_norm, foreach=True)
    learner.policy_opt.step()
    learner.replay.update_priorities(idx, per_sample.detach().numpy())
    learner.num_steps += 1
    learner.update_targets()


def test_run_takes_exactly_the_written_out_step() -> None:
    """Same seed, inserts, batch and priorities: the networks, targets and priorities after 7
    steps of ``run`` (in calls of 3, 1 and 3) equal the reference step's, bit for bit."""
    new, old = filled_learner(), filled_learner()
    for steps in (3, 1, 3):  # target copies every 3 steps: calls cross a copy
        metrics = new.run(steps)
        for _ in range(steps):
            reference_step(old)
    assert metrics["steps"] == 7 == old.num_steps
    assert_same(new, old)


def _recording_samples(learner: D4PGLearner) -> list[np.ndarray]:
    """Every index the learner's replay draws from now on, as host arrays, in order."""
    drawn, sample = [], learner.replay.sample

    def record(n: int, beta: float):  # noqa: ANN202
        out = sample(n, beta)
        drawn.append(learner.replay.backend.to_numpy(out[1]))
        return out

    learner.replay.sample = record
    return drawn


def test_a_replay_on_the_learners_device_samples_what_the_host_replay_does() -> None:
    """What the two homes guarantee, and no more. The host replay raises priorities to alpha
    with numpy, the device replay with torch: the two may take different SIMD paths for the
    same power and differ in the last bit or two of a float64 (seen: 32 of 390 leaves one ulp
    apart on one CPU, none on another). So: the same indices drawn at every step (a stratum's
    draw moves only if it lands within an ulp of a prefix-sum boundary), the same updates to
    float32's own tolerance (weights are float64 ratios rounded to float32), and priorities
    within 4 ulps of each other; inserts, counters and the generator's state exactly equal."""
    host, device = filled_learner(replay_device="host"), filled_learner(replay_device="learner")
    assert host.replay.backend.on_host and not device.replay.backend.on_host
    assert isinstance(device.replay.storage["obs"], torch.Tensor)
    drawn = [_recording_samples(host), _recording_samples(device)]
    for _ in range(3):
        metrics = [host.run(4), device.run(4)]
        new = transitions(30, seed=9)
        host.add(new)
        device.add(new)
    assert len(drawn[0]) == len(drawn[1]) == 12
    for a, b in zip(*drawn, strict=True):
        np.testing.assert_array_equal(a, b)
    assert metrics[1] == pytest.approx(metrics[0], rel=1e-6)
    _assert_same_to_ulps(host, device)
    assert device.replay.max_priority == pytest.approx(host.replay.max_priority, rel=1e-6)
    # Its state is the host replay's, so checkpoints move between the two.
    a, b = host.replay.state_dict(), device.replay.state_dict()
    for key in ("obs", "action", "reward", "discount", "next_obs", "counters"):
        np.testing.assert_array_equal(a[key], b[key])
    np.testing.assert_array_max_ulp(a["priorities"], b["priorities"], maxulp=4)
    assert a["rng_state"] == b["rng_state"]
    host.replay.load_state_dict(b)
    assert host.run(2) == pytest.approx(device.run(2), rel=1e-6)
    np.testing.assert_array_equal(drawn[0][-1], drawn[1][-1])


def _assert_same_to_ulps(a: D4PGLearner, b: D4PGLearner) -> None:
    for x, y in zip(net_params(a), net_params(b), strict=True):
        torch.testing.assert_close(x, y)  # float32's default rtol 1.3e-6, atol 1e-5
    leaves = np.arange(len(a.replay))
    np.testing.assert_array_max_ulp(
        a.replay.backend.to_numpy(a.replay.sum_tree.leaves(leaves)),
        b.replay.backend.to_numpy(b.replay.sum_tree.leaves(leaves)),
        maxulp=4,
    )


def test_blocks_of_batches_sampled_at_once() -> None:
    """``sgd_steps_per_sample`` 4: one sample of 4 batches per 4 steps, each batch a strided
    quarter (so it spans every stratum), each batch's priorities written after its step."""
    learner = filled_learner(sgd_steps_per_sample=4)
    sampled, written = [], []
    sample, update = learner.replay.sample, learner.replay.update_priorities

    def record_sample(n: int, beta: float):  # noqa: ANN202
        out = sample(n, beta)
        sampled.append(out[1])
        return out

    def record_update(idx: np.ndarray, priorities: np.ndarray) -> None:
        written.append(np.asarray(idx))
        update(idx, priorities)

    learner.replay.sample, learner.replay.update_priorities = record_sample, record_update
    metrics = learner.run(10)  # 4 + 4 + a block of 2
    b = learner.config.batch_size
    assert [len(s) for s in sampled] == [4 * b, 4 * b, 2 * b] and metrics["steps"] == 10
    assert len(written) == 10
    for j in range(4):
        np.testing.assert_array_equal(written[j], sampled[0][j::4])
    # The strata are ordered, so a strided quarter reaches across the whole tree.
    assert written[0].max() - written[0].min() > 0.8 * len(learner.replay)


def test_bf16_autocast_learns_like_float32() -> None:
    fp32, bf16 = filled_learner(), filled_learner(bf16=True)
    a, b = fp32.run(6), bf16.run(6)
    assert all(np.isfinite(v) for v in b.values())
    assert b["critic_loss"] == pytest.approx(a["critic_loss"], rel=0.05)
    assert all(p.dtype == torch.float32 for p in bf16.critic.parameters())


def test_compiled_losses_give_the_eager_updates() -> None:
    eager, compiled = filled_learner(), filled_learner(compile="default")
    for _ in range(2):
        a, b = eager.run(2), compiled.run(2)
    assert b["critic_loss"] == pytest.approx(a["critic_loss"], rel=1e-4)
    assert_same(eager, compiled, atol=1e-5)


@pytest.mark.parametrize(
    ("field", "value"),
    [("replay_device", "gpu"), ("sgd_steps_per_sample", 0), ("compile", "fast"),
     ("num_threads", -1)],
)  # fmt: skip
def test_bad_settings_are_refused_by_name(field: str, value: object) -> None:
    with pytest.raises(ConfigError, match=f"D4PGConfig.{field}="):
        small_config(**{field: value})
