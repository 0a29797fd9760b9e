"""Rollout worker, learner service and evaluator as plain classes (no Ray) on Pendulum-v1."""

from __future__ import annotations

import time
from dataclasses import replace
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

from robogym_ray.envs.outcomes import SERVER_RESTARTED
from robogym_ray.envs.outcomes import rates as status_rates
from robogym_ray.errors import ConfigError, RobotServerError
from robogym_ray.experience.evaluator import Evaluator
from robogym_ray.experience.rollout import RolloutWorker, box_dims, make_gym_env
from robogym_ray.learner.checkpoint import REPLAY_SUFFIX
from robogym_ray.learner.config import D4PGConfig
from robogym_ray.learner.service import LearnerService
from robogym_ray.protocol.client import Deadlines
from robogym_ray.storage import RunStorage
from robogym_ray.training.config import TrainConfig
from robogym_ray.training.program import seed_checkpoint
from robogym_ray.training.setup import noise_scale
from tests.distributed.conftest import free_port

SMALL = D4PGConfig(
    policy_hidden=(32, 32),
    critic_hidden=(32, 32),
    batch_size=32,
    min_replay_size=128,
    v_min=-1500.0,
    v_max=0.0,
    samples_per_insert=32.0,
    replay_capacity=10_000,
)


def test_worker_collects_nstep_transitions_and_episodes() -> None:
    worker = RolloutWorker(make_gym_env("Pendulum-v1"), SMALL, index=3, seed=1)
    result = worker.collect(450)  # two full 200-step episodes and a partial one
    assert result.steps == 450 and result.worker == 3
    assert [e.length for e in result.episodes] == [200, 200]
    # Every step of a finished episode yields a transition; the 50 pending steps of the third
    # episode yield those whose 5-step window is complete.
    assert len(result.batch["reward"]) == 400 + 50 - (SMALL.n_step - 1)
    disc = result.batch["discount"]
    # Pendulum only truncates: every transition bootstraps; full windows carry gamma^n and the
    # windows shortened at the time limit carry gamma^m, m < n.
    assert np.all(disc > 0)
    assert np.isclose(np.median(disc), SMALL.discount**SMALL.n_step)
    assert np.isclose(disc.max(), SMALL.discount)
    assert np.all(np.abs(result.batch["action"]) <= 1.0)


class _CrashingEnv(gym.Wrapper):
    """Pendulum whose step 7 reports a robot-server restart, as the Sim envs do."""

    def __init__(self) -> None:
        super().__init__(gym.make("Pendulum-v1"))
        self.t = 0

    def step(self, action):  # type: ignore[no-untyped-def]
        self.t += 1
        obs, r, term, trunc, info = self.env.step(action)
        if self.t == 7:
            return obs, r, False, True, {"final_status": SERVER_RESTARTED}
        return obs, r, term, trunc, info


def test_noise_scale_shrinks_the_workers_exploration() -> None:
    worker = RolloutWorker(make_gym_env("Pendulum-v1"), SMALL, sigma=0.4, seed=2)
    weights = {k: v.numpy() for k, v in worker.actor.policy.state_dict().items()}
    worker.set_weights(weights, 0)

    def policy_gap(batch: dict[str, np.ndarray]) -> float:
        # The first n_step - 1 windows began in the previous call, under its noise.
        obs, action = batch["obs"][SMALL.n_step - 1 :], batch["action"][SMALL.n_step - 1 :]
        greedy = np.stack([worker.actor.act(o, explore=False) for o in obs])
        return float(np.abs(action - greedy).max())

    noisy = worker.collect(60).batch
    assert noisy is not None and policy_gap(noisy) > 0.1 and worker.actor.sigma == 0.4
    quiet = worker.collect(60, noise_scale=0.0).batch
    assert quiet is not None and policy_gap(quiet) < 1e-6  # no noise left: the greedy action
    worker.collect(5, noise_scale=0.25)
    assert worker.actor.sigma == pytest.approx(0.1) and worker.sigma == 0.4  # base kept
    for bad in (-0.5, float("nan"), float("inf")):
        with pytest.raises(ValueError, match="noise_scale"):
            worker.collect(5, noise_scale=bad)
    assert worker.total_steps == 125  # the refused calls took no step


def test_noise_schedule_decays_linearly_over_env_steps() -> None:
    cfg = TrainConfig(sigma_decay_start=1000, sigma_decay_steps=500, sigma_final_scale=0.2)
    scales = [noise_scale(cfg, n) for n in (0, 1000, 1250, 1500, 10**6)]
    assert scales == pytest.approx([1.0, 1.0, 0.6, 0.2, 0.2])
    assert noise_scale(TrainConfig(sigma_final_scale=0.2), 10**6) == 1.0  # no decay steps
    for bad in ({"sigma_final_scale": 1.5}, {"sigma_decay_steps": -1}):
        with pytest.raises(ConfigError, match=next(iter(bad))):
            TrainConfig(**bad)


def test_server_restart_drops_the_unfinished_window() -> None:
    worker = RolloutWorker(_CrashingEnv, SMALL, seed=0)
    result = worker.collect(10)
    # Steps 1-2 completed 5-step windows before the crash; steps 3..7 were dropped.
    assert len(result.batch["reward"]) == 2
    assert result.dropped == 5
    assert result.episodes[0].final_status == SERVER_RESTARTED
    # No transition bootstraps from an observation after the crash: all have full windows.
    assert np.allclose(result.batch["discount"], SMALL.discount**5)


def test_learner_service_pays_samples_per_insert_and_checkpoints(tmp_path: Path) -> None:
    worker = RolloutWorker(make_gym_env("Pendulum-v1"), SMALL, seed=0)
    service = LearnerService(SMALL, 3, 1, checkpoint_dir=str(tmp_path), checkpoint_every=20)
    metrics = service.add(worker.collect(100).batch)
    assert metrics["steps_this_call"] == 0  # below min_replay_size: nothing owed yet
    batch = worker.collect(100).batch  # the episode ends: 100 + 4 flushed transitions
    metrics = service.add(batch)
    # Each transition inserted once learning may start pays 32 samples / 32 per batch = 1 step.
    assert metrics["learner_steps"] == len(batch["reward"]) == 104
    assert np.isfinite(metrics["critic_loss"])
    assert (tmp_path / "learner.pt").exists()

    weights, version = service.get_weights()
    restarted = LearnerService(SMALL, 3, 1, checkpoint_dir=str(tmp_path), checkpoint_every=20)
    assert restarted.restored_from_step > 0 and restarted.version == restarted.restored_from_step
    w2, _ = restarted.get_weights()
    checkpointed = {k: np.allclose(weights[k], w2[k]) for k in weights}
    assert version == restarted.version or not all(checkpointed.values())


def test_learner_service_hands_the_evaluator_the_policy_average() -> None:
    worker = RolloutWorker(make_gym_env("Pendulum-v1"), SMALL, seed=0)
    service = LearnerService(replace(SMALL, policy_average_tau=0.1), 3, 1)
    for _ in range(3):
        service.add(worker.collect(100).batch)
    worker.close()
    (online, version), (averaged, eval_version) = service.get_weights(), service.get_eval_weights()
    assert version == eval_version > 0
    expected = service.learner.policy_average.state_dict()["net.0.weight"].numpy()
    np.testing.assert_array_equal(averaged["net.0.weight"], expected)
    assert not np.allclose(online["net.0.weight"], averaged["net.0.weight"])


def test_evaluator_reports_rates() -> None:
    worker = RolloutWorker(make_gym_env("Pendulum-v1"), SMALL)
    service = LearnerService(SMALL, 3, 1)
    evaluator = Evaluator(make_gym_env("Pendulum-v1"), SMALL)
    weights, version = service.get_weights()
    stats = evaluator.evaluate(weights, version, episodes=2)
    assert stats["eval_episodes"] == 2 and stats["eval_timeout_rate"] == 1.0
    assert -2000 < stats["eval_return"] < 0
    worker.close()
    assert status_rates(["success", "collision", "success", "max_steps_exceeded"]) == {
        "success_rate": 0.5,
        "collision_rate": 0.25,
        "timeout_rate": 0.25,
        "other_rate": 0.0,
    }


def test_non_box_spaces_are_refused() -> None:
    with pytest.raises(ConfigError, match="Box"):
        box_dims(gym.make("CartPole-v1"))


def test_real_robot_failure_abandons_the_episode_and_waits_for_the_robot() -> None:
    from robogym_ray.robots.server import start_robot_server

    server = start_robot_server("mir100", scene="lab_6x8", seed=0)
    port = server.port
    env_kwargs = {"rs_address": server.address, "deadlines": Deadlines.fast()}
    worker = RolloutWorker(
        make_gym_env("RoboGymRay/ObstacleAvoidanceMir100Rob-v0", env_kwargs), SMALL, seed=0
    )
    worker.retry_wait_s = 0.01
    assert worker.collect(10).steps == 10
    server.stop()  # the "robot" goes away mid-episode
    result = worker.collect(10)
    assert result.robot_errors == 1 and result.paused
    assert result.episodes[-1].final_status == "robot_error"
    assert result.batch is None  # the unfinished window was dropped, not flushed
    server = start_robot_server("mir100", scene="lab_6x8", seed=0, port=port)
    try:
        deadline = time.monotonic() + 30  # gRPC may back off before reconnecting
        while worker.collect(5).steps == 0 and time.monotonic() < deadline:
            pass
        assert worker.collect(5).steps == 5  # the worker carried on with the robot back
    finally:
        server.stop()
        worker.close()


def test_a_real_robot_down_when_its_worker_starts_is_waited_for_as_a_paused_one() -> None:
    """The worker starts (a real robot's worker is never replaced); its first collect finds
    the robot not ready, as a paused one, and the episode starts from the seed chosen at the
    start once the robot answers. A simulated worker's start fails instead, to be replaced."""
    from robogym_ray.robots.server import start_robot_server

    port = free_port()  # nothing listens there yet
    env_kwargs = {"rs_address": f"127.0.0.1:{port}", "deadlines": Deadlines.fast()}
    make = make_gym_env("RoboGymRay/ObstacleAvoidanceMir100Rob-v0", env_kwargs)
    with pytest.raises(RobotServerError):
        RolloutWorker(make, SMALL, seed=7)
    worker = RolloutWorker(make, SMALL, seed=7, real_robot=True)
    worker.retry_wait_s = 0.01
    result = worker.collect(10)
    assert result.steps == 0 and result.paused and result.episodes == []
    server = start_robot_server("mir100", scene="lab_6x8", seed=0, port=port)
    try:
        deadline = time.monotonic() + 30  # gRPC may back off before reconnecting
        while worker.collect(5).steps == 0 and time.monotonic() < deadline:
            pass
        assert worker.collect(5).steps == 5
        assert worker.slots[0].start == (7, False) and worker.slots[0].pending_start is None
    finally:
        server.stop()
        worker.close()


def test_final_checkpoint_carries_the_replay_and_periodic_ones_drop_it(tmp_path: Path) -> None:
    worker = RolloutWorker(make_gym_env("Pendulum-v1"), SMALL, seed=0)
    service = LearnerService(SMALL, 3, 1, checkpoint_dir=str(tmp_path), checkpoint_every=0)
    service.add(worker.collect(200).batch)
    replay_file = tmp_path / f"learner.pt{REPLAY_SUFFIX}"
    service.checkpoint(include_replay=True)
    assert replay_file.exists()
    restored = LearnerService(SMALL, 3, 1, checkpoint_dir=str(tmp_path))
    assert len(restored.learner.replay) == len(service.learner.replay) > 0
    # A checkpoint without replay must not leave the older replay paired with newer networks.
    service.checkpoint()
    assert not replay_file.exists()
    assert len(LearnerService(SMALL, 3, 1, checkpoint_dir=str(tmp_path)).learner.replay) == 0


def test_init_from_is_checked_before_any_actor_starts(tmp_path: Path) -> None:
    source = tmp_path / "old" / "learner.pt"
    LearnerService(SMALL, 3, 1, checkpoint_dir=str(source.parent)).checkpoint()
    storage = RunStorage(str(tmp_path / "new"))
    run_dir = tmp_path / "new" / "checkpoints"
    with pytest.raises(ConfigError, match="no such checkpoint"):
        seed_checkpoint(str(tmp_path / "missing.pt"), storage, SMALL, 3, 1)
    with pytest.raises(ConfigError, match="obs_dim=4"):  # another task's observation size
        seed_checkpoint(str(source), storage, SMALL, 4, 1)
    assert not run_dir.exists()  # a refused checkpoint leaves nothing behind
    assert seed_checkpoint(str(source), storage, SMALL, 3, 1)
    assert (run_dir / "learner.pt").read_bytes() == source.read_bytes()
    # A resumed run keeps its own, newer checkpoint.
    (run_dir / "learner.pt").write_bytes(b"newer")
    assert not seed_checkpoint(str(source), storage, SMALL, 3, 1)
    assert (run_dir / "learner.pt").read_bytes() == b"newer"
