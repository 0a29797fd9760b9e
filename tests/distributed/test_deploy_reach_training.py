"""The isaac-deploy-reach-ur10e-average-quarter-ratio-pose-critic experiment end to end,
CI-sized: a training from its config file (the deploy reach's preset and support, policy
averaging, a quarter of the replay ratio, the critic's pose features; small networks and
replay, a short warm-up), then ``evaluate`` of the averaged policy on the deploy reach's env:
the critic read its features, the policy that runs is ``obs -> action`` as Isaac Lab's are."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import torch

import robogym_ray
from robogym_ray.cli import main as cli_main
from robogym_ray.envs.ur_deploy_features import DeployReachPose
from robogym_ray.export import load_checkpoint_policy
from robogym_ray.learner.checkpoint import read as read_checkpoint

pytestmark = [pytest.mark.ray, pytest.mark.slow, pytest.mark.usefixtures("ray_cluster")]

CONFIG = (
    Path(__file__).resolve().parents[2]
    / "experiments/configs/isaac-deploy-reach-ur10e-average-quarter-ratio-pose-critic.json"
)
ENV_ID = "RoboGymRay/IsaacDeployReachUR10eSim-v0"
# Small networks, few learner steps: the path is under test, not the learning.
SMALL = {"policy_hidden": [32, 32], "critic_hidden": [32, 32], "min_replay_size": 100,
         "batch_size": 16, "replay_capacity": 20_000}  # fmt: skip


def test_a_short_training_with_the_critics_pose_features_runs_and_is_scored(
    tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    summary = robogym_ray.train(
        str(CONFIG), d4pg=SMALL, workers=1, envs_per_worker=1, total_steps=300,
        random_steps=100, logdir=str(tmp_path), run_name="smoke", progress=False,
        video_interval_s=0.0, final_eval_episodes=1,
    )  # fmt: skip
    assert summary["task"] == ENV_ID
    assert summary["env_steps"] >= 300 and summary["learner_steps"] > 0
    assert summary["lost_transitions"] == 0
    config = json.loads((tmp_path / "smoke" / "config.json").read_text())
    assert config["d4pg"]["critic_features"] == "ur10e-deploy-pose"
    assert config["d4pg"]["samples_per_insert"] == 8.0
    # The critic read 19 observations, 6 actions and the 26 features; the policy, 19.
    checkpoint = tmp_path / "smoke" / "checkpoints" / "learner.pt"
    nets = read_checkpoint(checkpoint, torch.device("cpu"))["nets"]
    assert nets["critic"]["net.0.weight"].shape[1] == 19 + 6 + DeployReachPose.dim
    policy, _ = load_checkpoint_policy(checkpoint)
    assert policy(torch.zeros(1, 19)).shape == (1, 6)
    argv = [str(tmp_path / "smoke"), "--env-id", ENV_ID, "--episodes", "1", "--max-steps", "30"]
    assert cli_main(["evaluate", *argv]) == 0
    scored = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert scored["env_id"] == ENV_ID and scored["policy"].endswith("#policy_average")
