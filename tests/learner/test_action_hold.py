"""The policy around the hold (``D4PGConfig.hold_residual``): the trainer's map, from the env's,
targets the joints where they are; the policy and the workers stay within the hold's
half-width; the critic reads the step from the hold; checkpoints and exports carry it. Nets
without a hold are unchanged, bit for bit (the env's own map: tests/envs/test_isaac_reach.py)."""

from __future__ import annotations

from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
import torch

import robogym_ray  # noqa: F401 - registers the ids
from robogym_ray.errors import ConfigError, FieldError
from robogym_ray.export import export_policy, load_checkpoint_policy, load_policy
from robogym_ray.learner.behaviour import BehaviourPolicy, to_env_action
from robogym_ray.learner.config import D4PGConfig
from robogym_ray.learner.learner import D4PGLearner
from robogym_ray.learner.networks import DistributionalCritic, Policy, set_action_part
from robogym_ray.training.setup import learner_networks, with_hold
from tests.learner.conftest import ACT, OBS, small_config, transitions

UR = "RoboGymRay/IsaacReachUR10Sim-v0"
# A hold on a toy of OBS=3, ACT=2: action 0 follows obs[2], action 1 follows obs[0].
INDEX, GAIN, OFFSET, RESIDUAL = (2, 0), (0.1, -0.2), (0.3, -0.1), 0.5
HALF = (0.05, 0.1)


def _hold_config(**kw: object) -> D4PGConfig:
    return small_config(
        hold_residual=RESIDUAL, hold_index=INDEX, hold_gain=GAIN, hold_offset=OFFSET, **kw
    )


def _obs(n: int, scale: float = 2.0) -> torch.Tensor:
    values = np.random.default_rng(1).standard_normal((n, OBS)) * scale
    return torch.as_tensor(values, dtype=torch.float32)


def _hold_of(obs: torch.Tensor) -> torch.Tensor:
    return torch.as_tensor(OFFSET) + torch.as_tensor(GAIN) * obs[:, list(INDEX)]


def test_nets_without_a_hold_compute_exactly_what_they_did_before_it() -> None:
    # The box's formula as it was: centre + half * tanh(...), and the critic reading
    # (a - centre) / half; the hold's gather and clamp change no bit of it.
    torch.manual_seed(0)
    policy, critic = Policy(OBS, ACT, (8,)), DistributionalCritic(OBS, ACT, (8,), 5)
    for net in (policy, critic):
        net.set_action_box((-0.2, 0.5), (0.2, 0.7))
    obs, action = _obs(64, scale=50.0), torch.rand(64, ACT) * 2 - 1
    center, half = policy.box_center, policy.box_half
    assert torch.equal(policy(obs), center + half * torch.tanh(policy.net(obs)))
    read = critic.net(torch.cat([obs, (action - center) / half], -1))
    assert torch.equal(critic(obs, action), read)


def test_the_policy_acts_within_the_half_width_of_the_hold_and_the_critic_reads_the_step() -> None:
    learner = D4PGLearner(_hold_config(), OBS, ACT, seed=0)
    learner.add(transitions(200))
    for _ in range(5):
        learner.step()
    obs = _obs(256)
    hold = _hold_of(obs)
    with torch.no_grad():
        actions = learner.policy(obs)
    half = torch.as_tensor(HALF)
    # Within the hold's band, and within [-1, 1] where the band crosses it.
    assert ((hold - half).clamp(-1, 1) - 1e-6 <= actions).all()
    assert (actions <= (hold + half).clamp(-1, 1) + 1e-6).all()
    assert (actions.abs() <= 1).all() and ((hold.abs() > 1).any()), "no hold beyond [-1, 1]"
    # A zero output is the hold itself.
    with torch.no_grad():
        learner.policy.net[-1].weight.zero_()
        learner.policy.net[-1].bias.zero_()
        torch.testing.assert_close(learner.policy(obs), hold.clamp(-1, 1))
    # The critic reads (a - hold) / half: the same weights with no hold read that step.
    plain = DistributionalCritic(OBS, ACT, (32, 32), learner.config.num_atoms)
    own = learner.critic.state_dict()
    plain.load_state_dict({k: v for k, v in own.items() if k.startswith("net.")})
    u = torch.rand(16, ACT) * 2 - 1
    with torch.no_grad():
        torch.testing.assert_close(
            learner.critic(obs[:16], hold[:16] + torch.as_tensor(HALF) * u), plain(obs[:16], u)
        )


def test_workers_explore_around_the_hold_on_its_scale_and_stay_within_it() -> None:
    learner = D4PGLearner(_hold_config(), OBS, ACT, seed=0)
    worker = BehaviourPolicy(OBS, ACT, (32, 32), sigma=0.05, seed=0)
    worker.set_weights(learner.get_weights())  # the hold travels as buffers
    obs = _obs(1)[0].numpy()
    hold = _hold_of(torch.as_tensor(obs)[None])[0].numpy()
    greedy = worker.act(obs, explore=False)
    noisy = np.array([worker.act(obs, explore=True) for _ in range(2000)])
    assert (np.abs(noisy - hold) <= np.array(HALF) + 1e-6).all()
    np.testing.assert_allclose((noisy - greedy).std(axis=0), 0.05 * np.array(HALF), rtol=0.1)


def test_checkpoints_and_both_exports_carry_the_hold(tmp_path: Path) -> None:
    learner = D4PGLearner(_hold_config(), OBS, ACT, seed=0)
    learner.save(tmp_path / "learner.pt")
    loaded, _ = load_checkpoint_policy(tmp_path / "learner.pt")
    obs = _obs(32)
    with torch.no_grad():
        assert torch.equal(loaded(obs), learner.policy(obs))
    for name in ("policy.pt", "policy.onnx"):
        export_policy(tmp_path / "learner.pt", tmp_path / name)
        exported = load_policy(tmp_path / name)
        got = np.stack([exported(o) for o in obs.numpy()])
        np.testing.assert_allclose(got, learner.policy(obs).detach().numpy(), atol=1e-6)


@pytest.mark.parametrize(
    "fields, named",
    [
        ({"hold_residual": -0.1}, "hold_residual"),
        ({"hold_residual": float("nan")}, "hold_residual"),
        ({"hold_residual": 0.5, "action_box_low": (0.0,), "action_box_high": (0.5,)},
         "hold_residual"),
        ({"hold_residual": 0.5, "hold_index": (0, 1), "hold_gain": (1.0,), "hold_offset": (0, 0)},
         "hold_index"),
        ({"hold_index": (0,), "hold_gain": (1.0,), "hold_offset": (0.0,)}, "hold_index"),
    ],
)  # fmt: skip
def test_a_malformed_hold_is_refused_by_its_field(fields: dict, named: str) -> None:
    with pytest.raises(FieldError, match=named):
        D4PGConfig(**fields)


def test_a_hold_the_trainer_has_not_filled_in_or_of_another_size_is_refused() -> None:
    with pytest.raises(ConfigError, match="fills in from the task's env"):
        set_action_part(Policy(OBS, ACT, (8,)), D4PGConfig(hold_residual=0.5))
    sizes = {"policy_hidden": (8,), "critic_hidden": (8,)}
    three = D4PGConfig(
        **sizes, hold_residual=0.5, hold_index=(0, 1, 2), hold_gain=(1,) * 3, hold_offset=(0,) * 3
    )
    with pytest.raises(ConfigError, match="hold_residual: a hold of 3 dimensions for 2 action"):
        learner_networks(three, OBS, ACT)


def test_a_task_without_a_hold_map_is_a_config_error() -> None:
    env = gym.make("Pendulum-v1")
    try:
        with pytest.raises(ConfigError, match="Pendulum-v1 has no hold_map"):
            with_hold(D4PGConfig(hold_residual=0.5), env, "Pendulum-v1")
        assert with_hold(D4PGConfig(), env, "Pendulum-v1") == D4PGConfig()  # none asked for
    finally:
        env.close()


def test_the_trainers_hold_for_isaac_reach_targets_the_observed_joints() -> None:
    env = gym.make(UR)  # no reset: the maps and the Box only, no server
    try:
        task = env.unwrapped
        d4pg = with_hold(D4PGConfig(hold_residual=0.5), env, UR)
        assert d4pg.hold_index == tuple(range(6))
        low, high = env.action_space.low, env.action_space.high
        # On the nets' [-1, 1] scale: offset + gain * (q - default) still targets q.
        q = task.joint_position + np.random.default_rng(0).uniform(-1, 1, 6)
        hold = np.asarray(d4pg.hold_offset) + np.asarray(d4pg.hold_gain) * (q - task.joint_position)
        np.testing.assert_allclose(task.joint_targets(to_env_action(hold, low, high)), q, atol=1e-5)
        # 0.5 rad of target a joint: the half-width on each dimension's share of its Box.
        share = 0.5 / task.scale * 2 / (high - low).astype(np.float64)
        np.testing.assert_allclose(d4pg.hold_half, share, rtol=1e-5)
    finally:
        env.close()


def test_weights_from_before_the_hold_load_without_one_into_a_net_that_has_one() -> None:
    # A checkpoint written before the hold has a box and no hold_* entries: the net keeps the
    # part it was trained in, whatever the config now asks.
    old = Policy(OBS, ACT, (8,))
    old.set_action_box((-0.2, 0.5), (0.2, 0.7))
    saved = {k: v for k, v in old.state_dict().items() if not k.startswith("hold_")}
    net = Policy(OBS, ACT, (8,))
    set_action_part(net, _hold_config())
    net.load_state_dict(saved)
    obs = _obs(16)
    with torch.no_grad():
        assert torch.equal(net(obs), old(obs))
