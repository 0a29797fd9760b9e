"""How a run ends, as a user meets it: Ctrl-C (SIGINT) on a real `robogym-ray train` process,
a run name that is taken, and a default name that never collides."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
import torch

from robogym_ray import children
from robogym_ray.training.config import TrainConfig
from robogym_ray.training.setup import run_place

pytestmark = [pytest.mark.slow]


@pytest.mark.usefixtures("ray_cluster")
def test_ctrl_c_stops_the_run_with_its_checkpoint_and_summary(tmp_path: Path) -> None:
    """The first SIGINT stops collection; the final checkpoint holds the last learner step the
    printed summary reports, and summary.json says the run was stopped, and by what. The
    process joins the suite's Ray (--address), as a driver on a cluster does: the embedded
    Ray's own start and stop are the S3 and disk-full tests'."""
    import ray

    argv = [sys.executable, "-m", "robogym_ray.cli", "train", "--task", "pendulum",
            "--workers", "1", "--total-steps", "10000000", "--logdir", str(tmp_path),
            "--run-name", "sig", "--checkpoint-every", "50", "--no-progress", "--json",
            "--no-evaluator",
            "--address", ray.get_runtime_context().gcs_address]  # fmt: skip
    env = {**os.environ, "RAY_AUTH_MODE": "disabled"}
    proc = children.popen(argv, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                          text=True)  # fmt: skip
    first = tmp_path / "sig" / "checkpoints" / "learner.pt"
    deadline = time.monotonic() + 240
    while not first.exists() and proc.poll() is None and time.monotonic() < deadline:
        time.sleep(0.5)
    assert first.exists(), proc.communicate(timeout=60)
    proc.send_signal(signal.SIGINT)
    out, err = proc.communicate(timeout=240)
    assert proc.returncode in (0, 130), err[-3000:]
    assert "SIGINT: stopping - writing the final checkpoint and summary" in err
    assert "Traceback" not in err and "KeyboardInterrupt" not in err, err[-3000:]
    printed = json.loads(out.strip().splitlines()[-1])
    summary = json.loads((tmp_path / "sig" / "summary.json").read_text())
    assert printed == summary
    assert summary["ended"] == "stopped" and summary["stopped_by"] == "SIGINT"
    assert summary["ended_by"] == "SIGINT" and not summary["resumed"]
    assert summary["learner_steps"] > 0
    assert int(torch.load(first, weights_only=True)["num_steps"]) == summary["learner_steps"]


def test_the_short_summary_says_a_stopped_run_stopped() -> None:
    from robogym_ray.training.command import summary_text

    summary = {"task": "Pendulum-v1", "env_steps": 1200, "episodes": 6, "learner_steps": 300,
               "wall_s": 9.5, "restarts": {}, "dropped_steps": 0, "robot_errors": 0,
               "checkpoint": "/r/sig/checkpoints/learner.pt", "logdir": "/r/sig",
               "ended": "stopped", "stopped_by": "SIGINT",
               "storage": {"node": "vm (10.0.0.1)"}}  # fmt: skip
    lines = summary_text(summary).splitlines()
    assert lines[0] == (
        "Stopped early by SIGINT: Pendulum-v1 trained 1,200 env steps, 6 episodes, "
        "300 learner steps in 9.5 s."
    )
    assert "  files:       /r/sig/  (on vm (10.0.0.1))" in lines
    summary |= {"ended": "completed"}
    assert summary_text(summary).startswith("Trained Pendulum-v1: 1,200 env steps")


def test_a_default_run_name_never_lands_in_another_run(tmp_path: Path) -> None:
    cfg = TrainConfig(task="pendulum", logdir=str(tmp_path))
    first = run_place(cfg, "Pendulum-v1").name
    (tmp_path / first).mkdir()  # a run that started in the same second
    second = run_place(cfg, "Pendulum-v1").name
    assert second == f"{first}-2"
    (tmp_path / second / "checkpoints").mkdir(parents=True)
    assert run_place(cfg, "Pendulum-v1").name == f"{first}-3"
    mine = run_place(TrainConfig(task="pendulum", logdir=str(tmp_path), run_name="mine"), "x")
    assert mine.name == "mine" and mine.root.location() == str(tmp_path)
    assert mine.storage.location() == str(tmp_path / "mine")  # the run's folder, once


def test_a_taken_run_name_is_refused_unless_resumed_and_only_for_its_task(
    tmp_path: Path,
) -> None:
    from robogym_ray.errors import ConfigError

    run = tmp_path / "dup"
    (run / "checkpoints").mkdir(parents=True)
    (run / "config.json").write_text(json.dumps({"train": {"task": "navigation"}}))
    nav = "RoboGymRay/ObstacleAvoidanceMir100Sim-v0"
    cfg = TrainConfig(task="navigation", logdir=str(tmp_path), run_name="dup")
    with pytest.raises(ConfigError, match="holds a run already: pass --resume"):
        run_place(cfg, nav)
    resume = TrainConfig(task="navigation", logdir=str(tmp_path), run_name="dup", resume=True)
    with pytest.raises(ConfigError, match="has no checkpoint to continue from"):
        run_place(resume, nav)
    (run / "checkpoints" / "learner.pt").write_bytes(b"x")
    run_place(resume, nav)  # the same task: continued
    with pytest.raises(ConfigError, match="is a run of .*Mir100.*, not .*UR10"):
        run_place(resume, "RoboGymRay/EndEffectorPositioningUR10Sim-v0")
