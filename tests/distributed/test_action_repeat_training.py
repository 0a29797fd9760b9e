"""A CI-sized training of the deploy reach at a quarter of its decision rate (``--action-repeat
4``, ``envs/repeat.py``): the workers' held decisions reach the learner, the evaluator plays at
the env's own 60 Hz."""

from __future__ import annotations

from pathlib import Path

import pytest

import robogym_ray

pytestmark = [pytest.mark.ray, pytest.mark.slow, pytest.mark.usefixtures("ray_cluster")]
REPEAT = 4


def test_a_short_training_at_a_quarter_of_the_deploy_reachs_rate(tmp_path: Path) -> None:
    # 200 decisions of one env: the first 720-step episode ends at its 180th (at the env's own
    # rate no episode would end in 200 steps).
    small = {"policy_hidden": [32, 32], "critic_hidden": [32, 32], "min_replay_size": 50,
             "batch_size": 16, "samples_per_insert": 2.0, "replay_capacity": 5_000}  # fmt: skip
    summary = robogym_ray.train(
        task="isaac-deploy-reach-ur10e", d4pg=small, workers=1, envs_per_worker=1,
        total_steps=200, random_steps=50, action_repeat=REPEAT, logdir=str(tmp_path),
        run_name="held", progress=False, video_interval_s=0.0, final_eval_episodes=1,
    )  # fmt: skip
    assert summary["env_steps"] >= 200 and summary["learner_steps"] > 0
    assert summary["episodes"] >= 1 and summary["lost_transitions"] == 0
    # The evaluator plays at the env's own 60 Hz: its episodes end by time, with window errors.
    assert summary["eval/timeout_rate"] == 1.0 and "eval/window_position_error" in summary
