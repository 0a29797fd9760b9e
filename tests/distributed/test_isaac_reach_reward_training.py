"""The isaac-reach-ur10-her-average-long-replay-box-fine-tanh-smooth experiment end to end,
CI-sized: a training from its config file (the isaac-reach-ur10-fine-tanh preset and support,
hindsight relabelling, policy averaging, the action box, the policy's change priced; small
networks and replay, a short warm-up), then ``evaluate`` of the averaged policy on robo-gym
2.1.0's IsaacReachUR10Sim-v0, the env its policies are scored on; and a training of it whose
evaluator plays that env (``eval_env_id``)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

import robogym_ray
from robogym_ray.cli import main as cli_main
from robogym_ray.export import load_checkpoint_policy
from robogym_ray.learner.checkpoint import BEST_POLICY_NAME

pytestmark = [pytest.mark.ray, pytest.mark.slow, pytest.mark.usefixtures("ray_cluster")]

CONFIG = (
    Path(__file__).resolve().parents[2]
    / "experiments/configs/isaac-reach-ur10-her-average-long-replay-box-fine-tanh-smooth.json"
)
ORIGINAL = "RoboGymRay/IsaacReachUR10Sim-v0"
# Small networks, few learner steps: the path is under test, not the learning.
SMALL = {"policy_hidden": [32, 32], "critic_hidden": [32, 32], "min_replay_size": 100,
         "batch_size": 16, "samples_per_insert": 2.0, "replay_capacity": 20_000}  # fmt: skip


def test_a_short_training_runs_and_evaluate_scores_it_on_isaac_reach_ur10(
    tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    # 370 steps on each of the two envs: each ends one 360-step episode, which is relabelled.
    summary = robogym_ray.train(
        str(CONFIG), d4pg=SMALL, workers=1, envs_per_worker=2,
        total_steps=740, random_steps=100, logdir=str(tmp_path), run_name="smoke",
        progress=False, video_interval_s=0.0, final_eval_episodes=1,
    )  # fmt: skip
    assert summary["task"] == "RoboGymRay/IsaacReachFineTanhUR10Sim-v0"
    assert summary["env_steps"] >= 740 and summary["learner_steps"] > 0
    # The config's four copies of each step of the two finished episodes reached the replay.
    assert summary["relabelled_transitions"] == 4 * 2 * 360, summary["final_status_counts"]
    assert summary["lost_transitions"] == 0
    # The variant ends only by time: its evaluator scores the window-end errors.
    assert summary["eval/timeout_rate"] == 1.0 and 0 < summary["eval/window_position_error"] < 3
    config = json.loads((tmp_path / "smoke" / "config.json").read_text())
    assert (config["d4pg"]["v_min"], config["d4pg"]["v_max"]) == (-4.0, 2.0)
    assert config["d4pg"]["policy_average_tau"] > 0 and config["train"]["relabel_goals"] == 4
    # The smoothness term ran: its measure of the replayed windows reached the summary.
    assert config["d4pg"]["policy_smoothness"] == 0.05 and summary["learner/policy_change"] > 0
    box = np.array([config["d4pg"]["action_box_low"], config["d4pg"]["action_box_high"]])
    policy, _ = load_checkpoint_policy(tmp_path / "smoke" / "checkpoints" / "learner.pt")
    np.testing.assert_allclose(policy.box_center.numpy(), box.mean(axis=0), atol=1e-6)
    # Its policy runs unchanged on robo-gym 2.1.0's env and is scored by that env's success.
    argv = [str(tmp_path / "smoke"), "--env-id", ORIGINAL, "--episodes", "2", "--max-steps", "30"]
    assert cli_main(["evaluate", *argv]) == 0
    scored = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert scored["env_id"] == ORIGINAL and scored["n_episodes"] == 2
    assert scored["policy"].endswith("#policy_average")  # the average, as the evaluator ran it
    assert "success_rate" in scored["rates"] and scored["median_position_error"] > 0


def test_the_evaluator_plays_isaac_reach_ur10_while_the_variant_trains(tmp_path: Path) -> None:
    # eval_env_id (a short name here): the greedy policy is scored on robo-gym 2.1.0's env, by
    # its success, and select_episodes keeps policy-best.pt by those episodes. The run's last
    # evaluator call is waited for, so one is scored however short the run.
    summary = robogym_ray.train(
        str(CONFIG), d4pg=SMALL, workers=1, envs_per_worker=1, total_steps=200,
        random_steps=100, logdir=str(tmp_path), run_name="elsewhere", progress=False,
        video_interval_s=0.0, final_eval_episodes=1, eval_env_id="isaac-reach-ur10",
        select_episodes=1,
    )  # fmt: skip
    assert summary["task"] == "RoboGymRay/IsaacReachFineTanhUR10Sim-v0"
    assert summary["eval_env_id"] == ORIGINAL
    # 2.1.0's episodes end at the target, in a collision or at their limit, and have no
    # command windows: the variant's evaluator always reports window errors (the test above).
    assert "eval/success_rate" in summary and "eval/window_position_error" not in summary
    assert summary["best_snapshot"]["snapshots_scored"] >= 1
    assert (tmp_path / "elsewhere" / "checkpoints" / BEST_POLICY_NAME).is_file()
