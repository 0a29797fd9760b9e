"""Evaluation: counts match the episodes; reports; the Rob variant on an emulated robot."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
from collections.abc import Iterator

import pytest

from robogym_ray import children
from robogym_ray.cli import main as cli_main
from robogym_ray.envs.outcomes import category
from robogym_ray.envs.registration import variant_id
from robogym_ray.errors import ConfigError
from robogym_ray.evaluation import (
    EvaluationConfig,
    evaluate,
    serve_args,
    write_result,
)
from robogym_ray.export import export_policy
from tests.experiments.conftest import NAVIGATION, POSITIONING, save_learner


def test_short_evaluation_counts_add_up(positioning_checkpoint, tmp_path) -> None:
    path, _ = positioning_checkpoint
    cfg = EvaluationConfig(env_id=POSITIONING, episodes=4, max_steps=5, seed=3)
    result = evaluate(path, cfg)
    assert len(result.episodes) == 4 and sum(result.counts.values()) == 4
    assert sum(result.rates.values()) == pytest.approx(1.0)
    assert [e.seed for e in result.episodes] == [3, 4, 5, 6]
    assert all(e.length <= 5 and len(e.target) == 3 for e in result.episodes)
    statuses = [category(e.final_status) for e in result.episodes]
    assert result.counts["timeout"] == statuses.count("timeout")
    # Same seeds, same policy: the same episodes.
    again = evaluate(path, cfg)
    assert [e.target for e in again.episodes] == [e.target for e in result.episodes]
    json_path, md_path = write_result(result, tmp_path / "out")
    data = json.loads(json_path.read_text())
    assert data["n_episodes"] == 4 and len(data["episodes"]) == 4
    assert data["counts"] == result.counts
    assert "| success | collision | timeout |" in md_path.read_text()


def test_ids_categories_and_checks(tmp_path) -> None:
    assert variant_id(NAVIGATION, "rob") == "RoboGymRay/ObstacleAvoidanceMir100Rob-v0"
    assert variant_id("RoboGymRay/ObstacleAvoidanceMir100Rob-v0", "sim") == NAVIGATION
    assert [category(s) for s in ("success", "collision", "max_steps_exceeded", "x")] == [
        "success", "collision", "timeout", "other"]  # fmt: skip
    assert serve_args(POSITIONING)[:4] == ["--robot", "ur10", "--scene", "empty"]
    assert serve_args(variant_id(POSITIONING, "rob")) == serve_args(POSITIONING)  # one server
    with pytest.raises(ConfigError, match="is not a RoboGymRay"):
        serve_args("Pendulum-v1")
    with pytest.raises(ConfigError, match="via_actor"):
        EvaluationConfig(via_actor=True)
    save_learner(tmp_path / "nav.pt", 20, 2)
    with pytest.raises(ConfigError, match="20 observations"):
        evaluate(tmp_path / "nav.pt", EvaluationConfig(env_id=POSITIONING, episodes=1))


@pytest.fixture
def emulated_ur10() -> Iterator[str]:
    """``robogym-ray serve --real-time --emulate-hardware`` for the positioning task."""
    proc = children.popen(
        [sys.executable, "-m", "robogym_ray.cli", "serve", "--real-time", "--emulate-hardware",
         "--seed", "1", *serve_args(POSITIONING)],
        stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True,
    )  # fmt: skip
    line = proc.stdout.readline().strip()  # type: ignore[union-attr]
    try:
        assert line.startswith("listening on "), line
        yield line.removeprefix("listening on ")
    finally:
        os.kill(proc.pid, signal.SIGTERM)
        proc.wait(timeout=20)


def test_serve_emulated_hardware_answers_and_runs_the_rob_variant(
    emulated_ur10: str, positioning_checkpoint, tmp_path, capsys
) -> None:
    path, _ = positioning_checkpoint
    policy = tmp_path / "policy.pt"
    export_policy(path, policy, env_id=POSITIONING)
    argv = ["run-policy", "--policy", str(policy), "--rs-address", emulated_ur10,
            "--episodes", "2", "--max-steps", "4", "--out", str(tmp_path / "ev")]  # fmt: skip
    assert cli_main(argv) == 0
    summary = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert summary["env_id"] == "RoboGymRay/EndEffectorPositioningUR10Rob-v0"
    assert summary["n_episodes"] == 2 and summary["counts"]["timeout"] == 2
    # Real-time pacing: 4 actions at 10 Hz take >= 0.4 s per episode.
    assert summary["wall_s"] >= 0.8


@pytest.mark.ray
@pytest.mark.slow
@pytest.mark.usefixtures("ray_cluster")
def test_evaluation_through_the_real_robot_actor(emulated_ur10: str, positioning_checkpoint):
    path, _ = positioning_checkpoint
    cfg = EvaluationConfig(
        env_id=POSITIONING, rs_address=emulated_ur10, episodes=1, max_steps=3, via_actor=True
    )
    result = evaluate(path, cfg)
    assert result.env_id.endswith("Rob-v0") and result.episodes[0].length == 3
