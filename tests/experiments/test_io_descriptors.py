"""Isaac Lab 3's IO_descriptors.yaml beside an exported policy: checked against the env before
the first action, its action term applied, a mismatch refused in one line.

The YAML is written here as Isaac Lab's exporter writes it (``yaml.safe_dump`` of the
descriptors of the policy group's observation terms, the action terms, the articulation and the
scene; ``isaaclab/envs/utils/io_descriptors.py``), for a policy made here with rsl_rl's exported
structure (``robogym_ray.isaac_lab_sample``).
"""

from __future__ import annotations

import copy
import json
import math
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import pytest
import torch
import yaml

from robogym_ray.evaluation import emulated_server
from robogym_ray.isaac_lab import IsaacLabPolicy
from robogym_ray.isaac_lab_sample import write_sample
from robogym_ray.learner.behaviour import to_env_action
from robogym_ray.robots.server import start_robot_server
from tests.experiments.test_isaac_lab import one_error_line, run_policy

SIM = "RoboGymRay/IsaacDeployReachUR10eSim-v0"
ROB = "RoboGymRay/IsaacDeployReachUR10eRob-v0"
JOINTS = [
    "shoulder_pan_joint",
    "shoulder_lift_joint",
    "elbow_joint",
    "wrist_1_joint",
    "wrist_2_joint",
    "wrist_3_joint",
]
DEFAULT = [math.pi, -math.pi / 2, math.pi / 2, -math.pi / 2, -math.pi / 2, 0.0]
OBS = "isaaclab.envs.mdp.observations"


def obs_term(name: str, size: int, kind: str, joints: bool) -> dict[str, Any]:
    term: dict[str, Any] = {
        "dtype": "torch.float32",
        "extras": {"description": name, "modifiers": None},
        "full_path": f"{OBS}.{name}",
        "mdp_type": "Observation",
        "name": name,
        "observation_type": kind,
        "shape": [size],
        "overloads": {
            "clip": None,
            "flatten_history_dim": True,
            "history_length": 0,
            "scale": None,
        },
    }
    if joints:
        term["joint_names"] = list(JOINTS)
    return term


def deploy_reach_descriptors() -> dict[str, Any]:
    """What Isaac Lab 3 exports for Isaac-Deploy-Reach-UR10e-v0 (its config's terms)."""
    action = {
        "action_type": "JointAction",
        "clip": None,
        "dtype": "torch.float32",
        "extras": {"description": "relative joint positions"},
        "full_path": "isaaclab.envs.mdp.actions.joint_actions.RelativeJointPositionAction",
        "joint_names": list(JOINTS),
        "mdp_type": "Action",
        "name": "relative_joint_position_action",
        "offset": 0.0,
        "scale": 0.0625,
        "shape": [6],
    }
    robot = {
        "joint_names": list(JOINTS),
        "default_joint_pos": list(DEFAULT),
        "default_joint_vel": [0.0] * 6,
    }
    return {
        "actions": [action],
        "articulations": {"robot": robot},
        "observations": {
            "policy": [
                obs_term("joint_pos", 6, "JointState", True),
                obs_term("joint_vel", 6, "JointState", True),
                obs_term("generated_commands", 7, "Command", False),
            ]
        },
        "scene": {"decimation": 2, "dt": 1 / 60, "physics_dt": 1 / 120},
    }


def write(folder: Path, data: dict[str, Any], name: str = "IO_descriptors.yaml") -> Path:
    path = folder / name
    path.write_text(yaml.safe_dump(data))
    return path


@pytest.fixture(scope="module")
def exported(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path, Any, Path]:
    folder = tmp_path_factory.mktemp("deploy") / "exported"
    pt, onnx, module = write_sample(folder, 19, 6)
    return pt, onnx, module, write(folder.parent, deploy_reach_descriptors())


def test_both_files_run_on_the_sim_id_with_their_descriptors(exported, capsys) -> None:
    pt, onnx, _, io = exported
    for path in (pt, onnx):
        summary = run_policy(
            capsys,
            "--isaac-lab",
            str(path),
            "--io-descriptors",
            str(io),
            "--env-id",
            SIM,
            "--episodes",
            "1",
            "--max-steps",
            "8",
        )
        assert summary["env_id"] == SIM and summary["n_episodes"] == 1
        assert summary["mean_position_error"] > 0


def test_the_declared_action_term_is_what_the_env_receives(exported, tmp_path) -> None:
    """scale 0.0625 x raw + offset, clipped as declared, reaches the env as its own action."""
    pt, _, module, _ = exported
    data = deploy_reach_descriptors()
    data["actions"][0]["clip"] = [[-0.005, 0.005]] * 6  # rad, on the processed action
    io = write(tmp_path, data)
    env = gym.make(SIM)
    try:
        obs, _ = env.reset(seed=0)
        unit = IsaacLabPolicy(pt, io).unit_policy(env)(obs)
        got = to_env_action(unit, env.action_space.low, env.action_space.high)
        with torch.no_grad():
            raw = module(torch.as_tensor(obs[None])).numpy()[0].astype(np.float64)
        np.testing.assert_allclose(got, np.clip(0.0625 * raw, -0.005, 0.005) / 0.0625, atol=1e-4)
        assert np.any(np.abs(0.0625 * raw) > 0.005)  # the clip did something
    finally:
        env.close()


def test_both_files_drive_an_emulated_ur10e(exported, capsys) -> None:
    pt, onnx, _, io = exported
    with emulated_server(SIM, seed=1) as address:
        for path in (pt, onnx):
            summary = run_policy(
                capsys,
                "--isaac-lab",
                str(path),
                "--io-descriptors",
                str(io),
                "--env-id",
                SIM,
                "--rs-address",
                address,
                "--episodes",
                "1",
                "--max-steps",
                "6",
            )
            assert summary["env_id"] == ROB and summary["rs_address"] == address
            assert summary["wall_s"] >= 0.1  # real time: 6 actions at 60 Hz


def swap(data: dict[str, Any], i: int, j: int) -> None:
    data[i], data[j] = data[j], data[i]


def mismatches() -> dict[str, tuple[dict[str, Any], tuple[str, ...]]]:
    """Each wrong file and the words its one-line refusal must contain."""
    cases = {}
    d = deploy_reach_descriptors()
    swap(d["observations"]["policy"], 0, 1)
    cases["term order"] = (d, ("observation term 0 is 'joint_vel'", "observes 'joint_pos'"))
    d = deploy_reach_descriptors()
    swap(d["observations"]["policy"][0]["joint_names"], 0, 2)
    cases["joint order"] = (
        d,
        (
            "observation term 'joint_pos' joint_names",
            "'elbow_joint', 'shoulder_lift_joint', 'shoulder_pan_joint'",
        ),
    )
    d = deploy_reach_descriptors()
    d["actions"][0]["scale"] = 0.5
    cases["action scale"] = (d, ("'relative_joint_position_action' scale 0.5", "is 0.0625"))
    d = deploy_reach_descriptors()
    d["scene"]["dt"], d["scene"]["decimation"] = 1 / 30, 4
    cases["control period"] = (d, ("scene dt 0.0333333 s", "acts every 0.0166667 s (60 Hz)"))
    d = deploy_reach_descriptors()
    d["observations"]["policy"][1] = obs_term("base_lin_vel", 6, "RootState", False)
    cases["unknown term"] = (d, ("observation term 1 'base_lin_vel'", "is not supported"))
    return cases


@pytest.mark.parametrize("case", list(mismatches()))
def test_a_mismatch_is_refused_in_one_line_before_any_action(
    exported, tmp_path, capfd, case
) -> None:
    pt, onnx, _, _ = exported
    data, words = mismatches()[case]
    io = write(tmp_path, copy.deepcopy(data))
    robot, scene, options = gym.make(SIM).unwrapped.server_spec()
    handle = start_robot_server(robot, scene=scene, options=options, seed=0)
    try:
        for path in (pt, onnx):
            line = one_error_line(
                capfd,
                "run-policy",
                "--isaac-lab",
                str(path),
                "--io-descriptors",
                str(io),
                "--env-id",
                SIM,
                "--rs-address",
                handle.address,
            )
            assert all(w in line for w in words), line
            assert str(io) in line
        # Refused before the env reset the robot, let alone sent it an action.
        assert handle.core.calls["set"] == 0 and handle.core.calls["action"] == 0
    finally:
        handle.stop()


def test_descriptors_of_another_task_or_without_a_policy_are_refused(
    exported, tmp_path, capfd
) -> None:
    pt, _, _, io = exported
    line = one_error_line(
        capfd,
        "evaluate",
        "--isaac-lab",
        str(pt),
        "--io-descriptors",
        str(io),
        "--env-id",
        "RoboGymRay/IsaacReachPandaSim-v0",
    )
    assert "maps 19 observations to 6 actions" in line
    line = one_error_line(capfd, "evaluate", str(pt), "--io-descriptors", str(io), "--env-id", SIM)
    assert "add --isaac-lab" in line
    short = deploy_reach_descriptors()
    del short["observations"]["policy"][2]
    line = one_error_line(
        capfd,
        "run-policy",
        "--isaac-lab",
        str(pt),
        "--io-descriptors",
        str(write(tmp_path, short)),
        "--env-id",
        SIM,
    )
    assert "observation terms add up to 12 values" in line and "takes 19" in line
    junk = tmp_path / "junk.yaml"
    junk.write_text("scene: [1, 2\n")
    line = one_error_line(
        capfd, "run-policy", "--isaac-lab", str(pt), "--io-descriptors", str(junk), "--env-id", SIM
    )
    assert "not YAML" in line


def test_isaac_reach_ur10_declares_isaac_lab_2s_terms(tmp_path, capsys) -> None:
    """The UR10 reach env checks Isaac-Reach-UR10-v0's descriptors (25 obs, absolute action)."""
    pt, _, _ = write_sample(tmp_path / "ur10", 25, 6)
    default = [0.0, -1.712, 1.712, 0.0, 0.0, 0.0]
    rel = obs_term("joint_pos_rel", 6, "JointState", True)
    rel["joint_pos_offsets"] = default
    data = deploy_reach_descriptors()
    data["observations"]["policy"] = [
        rel,
        obs_term("joint_vel_rel", 6, "JointState", True),
        obs_term("generated_commands", 7, "Command", False),
        obs_term("last_action", 6, "Action", False),
    ]
    data["actions"][0].update(
        full_path="isaaclab.envs.mdp.actions.joint_actions.JointPositionAction",
        name="joint_position_action",
        scale=0.5,
        offset=default,
    )
    data["articulations"]["robot"]["default_joint_pos"] = default
    data["scene"]["dt"] = 1 / 30
    summary = run_policy(
        capsys,
        "--isaac-lab",
        str(pt),
        "--io-descriptors",
        str(write(tmp_path, data)),
        "--env-id",
        "RoboGymRay/IsaacReachUR10Sim-v0",
        "--episodes",
        "1",
        "--max-steps",
        "3",
    )
    assert summary["n_episodes"] == 1
    assert json.dumps(summary)  # the usual report


@pytest.mark.ray
@pytest.mark.slow
@pytest.mark.usefixtures("ray_cluster")
def test_the_deploy_parts_commands_run(exported, tmp_path, capsys) -> None:
    """docs/isaac-lab.md's Isaac Lab 3 commands as written, IO this test's descriptors."""
    from tests.experiments.test_isaac_lab import run_page_commands

    pt, onnx, _, io = exported
    run_page_commands(1, (pt, onnx), tmp_path, capsys, {"IO": str(io)})


class _ExpertExport(torch.nn.Module):
    """The scripted expert in rsl_rl's exported shape (an ``actor`` whose first and last Linear
    give the sizes), answering 4x its actions: raw outputs beyond [-1, 1] for the decoder to
    clamp back."""

    def __init__(self, quat_order: str) -> None:
        super().__init__()
        from robogym_ray.envs.ur_deploy_expert import DeployReachExpert

        self.actor = torch.nn.Sequential(torch.nn.Linear(19, 6))
        torch.nn.init.zeros_(self.actor[0].weight)
        torch.nn.init.zeros_(self.actor[0].bias)
        self.expert = DeployReachExpert(quat_order)

    def forward(self, obs: torch.Tensor) -> torch.Tensor:
        return 4.0 * self.expert(obs) + self.actor(obs)


def test_an_exported_expert_tracks_through_isaac_ross_decoder(tmp_path, capsys) -> None:
    """TorchScript of the scripted expert, trained (as Isaac Lab 2.x) on w-x-y-z commands, run
    the Isaac ROS way: clamp, scale 0.0625, one target per step to the servo; the table shows
    the task's own measure, the window-end errors."""
    pt = tmp_path / "policy.pt"
    torch.jit.script(_ExpertExport("wxyz")).save(str(pt))
    io = write(
        tmp_path, deploy_reach_descriptors(), "isaac_deploy_reach_ur10e_v0_IO_descriptors.yaml"
    )
    summary = run_policy(capsys, "--isaac-lab", str(pt), "--io-descriptors", str(io),
                         "--env-id", SIM, "--quat-order", "wxyz", "--episodes", "1",
                         "--max-steps", "240", "--out", str(tmp_path / "ev"))  # fmt: skip
    # One 4-s window from seed 1000's start: reached (the 100-episode score: docs/results).
    assert summary["median_window_position_error"] < 0.01
    assert summary["median_window_rotation_error"] < 0.05
    table = (tmp_path / "ev" / "evaluation.md").read_text()
    assert "median window position error (m) | median window rotation error (rad) |" in table


def test_the_decoder_clamps_then_filters_and_restarts_each_episode(exported) -> None:
    pt, _, module, io = exported
    env = gym.make(SIM)
    try:
        obs, _ = env.reset(seed=0)
        decoder = IsaacLabPolicy(pt, io).unit_policy(env, ema_alpha=0.25)
        obs2 = obs + np.float32(0.5)
        with torch.no_grad():
            raw = [
                module(torch.as_tensor(o[None])).numpy()[0].astype(np.float64) for o in (obs, obs2)
            ]
        first = 0.25 * np.clip(raw[0], -1, 1)  # from zero at the episode's start
        np.testing.assert_allclose(decoder(obs), first, atol=1e-5)
        np.testing.assert_allclose(
            decoder(obs2), 0.25 * np.clip(raw[1], -1, 1) + 0.75 * first, atol=1e-5
        )
        decoder.reset()
        np.testing.assert_allclose(decoder(obs), first, atol=1e-5)
    finally:
        env.close()


def test_the_decoders_options_are_refused_where_they_mean_nothing(exported) -> None:
    from robogym_ray.errors import ConfigError
    from robogym_ray.evaluation import EvaluationConfig, evaluate

    for kwargs, match in (
        ({"ema_alpha": 0.5}, "--ema-alpha is for an Isaac Lab policy"),
        ({"quat_order": "wxyz"}, "--quat-order is for an Isaac Lab policy"),
        ({"isaac_lab": True, "env_id": SIM, "ema_alpha": 0.0}, r"ema_alpha must be in \(0, 1\]"),
        ({"isaac_lab": True, "env_id": SIM, "quat_order": "zyxw"}, "quat_order must be"),
    ):
        with pytest.raises(ConfigError, match=match):
            EvaluationConfig(**kwargs)
    cfg = EvaluationConfig(isaac_lab=True, env_id="RoboGymRay/IsaacReachUR10Sim-v0",
                           quat_order="wxyz", episodes=1)  # fmt: skip
    with pytest.raises(ConfigError, match="--quat-order: .* observes no Isaac Lab command"):
        evaluate(exported[0], cfg)
