"""experiments/peers.py: a peer trains on a wall-clock budget and its snapshots are scored by
the same greedy episodes as ``robogym-ray evaluate`` (plumbing, not learning)."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import pytest

from robogym_ray import children
from tests.experiments.test_scripts import script


def needs_sb3() -> None:
    pytest.importorskip("stable_baselines3")  # the [peers] extra; RLlib's environment lacks it


@pytest.mark.parametrize("algo", ["sb3-td3", "sb3-sac"])
def test_a_peer_saves_snapshots_by_wall_time_and_each_is_scored(
    tmp_path: Path, algo: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    needs_sb3()
    peers = script("peers")
    out = tmp_path / algo
    temp = tmp_path / "temp"  # where SB3's default logger would make its SB3-<date> folder
    temp.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(temp))
    monkeypatch.delenv("SB3_LOGDIR", raising=False)
    record = peers.train(algo, "navigation", minutes=0.04, seed=0, out=out, save_every_min=0.02)
    assert not list(temp.glob("SB3-*"))
    assert [s["wall_min"] for s in record["snapshots"]] == [0.02, 0.04]
    assert record["complete"] is True
    assert json.loads((out / "run.json").read_text()) == record
    steps = [s["env_steps"] for s in record["snapshots"]]
    assert 0 < steps[0] < steps[1] == record["env_steps"]
    # SB3's off-policy defaults: one gradient update per env step once learning starts (100
    # steps); the budget can end a step after its env step, before its update.
    assert record["env_steps"] - 101 <= record["gradient_updates"] <= record["env_steps"] - 100
    curve = peers.evaluate(out, episodes=2, seed=1000)
    assert json.loads((out / "curve.json").read_text()) == curve
    assert [c["wall_min"] for c in curve] == [0.02, 0.04]
    for point in curve:
        rates = [point[f"{k}_rate"] for k in ("success", "collision", "timeout", "other")]
        assert point["episodes"] == 2 and sum(rates) == pytest.approx(1.0)
    if algo == "sb3-sac":
        points = peers.exploration(out, episodes=3)
        assert json.loads((out / "exploration.json").read_text()) == points
        assert [p["wall_min"] for p in points] == [0.02, 0.04]
        assert all(0 < p["ent_coef"] <= 1 and p["policy_std"] > 0 for p in points)
        assert all(0 < p["action_std"] < 1 for p in points)  # actions in [-1, 1]
        assert peers.exploration(out, episodes=3) == points  # the samples' seed is fixed
        # The command line reads the same episodes as `evaluate` does: its flags reach it.
        assert peers.main(["exploration", str(out), "--episodes", "3", "--seed", "1000"]) == 0
        assert json.loads((out / "exploration.json").read_text()) == points
        if record["gradient_updates"] > 0:  # none on a machine too loaded to pass 100 steps
            # SB3 updates at every step past the first 100, and SAC's entropy coefficient
            # (from 1.0, SB3's "auto") moves at every update: each snapshot read from its file.
            assert points[-1]["ent_coef"] < 1
            measured = ("ent_coef", "policy_std", "action_std")
            assert [points[0][k] for k in measured] != [points[1][k] for k in measured]
    else:
        with pytest.raises(SystemExit, match="sb3-sac and rllib-ppo runs, not sb3-td3"):
            peers.exploration(out)


def test_a_run_killed_after_a_snapshot_keeps_its_record_and_can_be_evaluated(
    tmp_path: Path,
) -> None:
    """run.json is rewritten at every snapshot: a run cut short (a reboot, SIGKILL) is not lost."""
    needs_sb3()
    out = tmp_path / "cut"
    cmd = [sys.executable, "experiments/peers.py", "train", "--algo", "sb3-td3",
           "--problem", "navigation", "--minutes", "60", "--save-every-min", "0.02",
           "--out", str(out)]  # fmt: skip
    repo = Path(__file__).resolve().parents[2]
    log = tmp_path / "train.log"  # a file, not a pipe: nothing reads it until the end
    with open(log, "wb") as sink:
        proc = children.popen(cmd, cwd=repo, stdout=sink, stderr=subprocess.STDOUT)
    try:
        deadline = time.monotonic() + 120
        while not (out / "run.json").exists():
            assert proc.poll() is None, log.read_text()[-2000:]
            assert time.monotonic() < deadline, "no snapshot within 120 s"
            time.sleep(0.2)
    finally:
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait()
    record = json.loads((out / "run.json").read_text())
    assert record["complete"] is False and record["minutes"] == 60
    saved = sorted(p.name for p in (out / "snapshots").glob("*.zip"))
    assert len(record["snapshots"]) >= 1
    # Every snapshot the record names is on disk (a later one may be, before its record is).
    named = [f"policy-{s['wall_min']:06.2f}min.zip" for s in record["snapshots"]]
    assert set(named) <= set(saved)
    curve = script("peers").evaluate(out, episodes=1, seed=1000)
    assert [c["wall_min"] for c in curve] == [s["wall_min"] for s in record["snapshots"]]


def test_a_training_runs_timed_snapshots_are_scored_like_a_peers(tmp_path: Path) -> None:
    """``peers.py evaluate`` on a ``robogym-ray train`` run: its ``policy-MMM.MMmin.pt`` files
    (what ``--policy-snapshot-every-s`` keeps) on the same episodes, into the same curve."""
    from robogym_ray.learner.config import D4PGConfig
    from robogym_ray.learner.service import LearnerService
    from robogym_ray.training.selection import PolicySnapshots
    from tests.experiments.conftest import NAVIGATION, save_learner

    run = tmp_path / "run"
    (run / "checkpoints").mkdir(parents=True)
    (run / "config.json").write_text(json.dumps({"train": {"task": NAVIGATION}}))
    cfg = D4PGConfig(policy_hidden=(16,), critic_hidden=(16,), num_atoms=11)
    snapshots = PolicySnapshots(run / "checkpoints", every_s=60.0)
    for minute in (1, 2):
        weights, _ = LearnerService(cfg, 20, 2, seed=minute).get_weights()
        snapshots.keep(minute, weights, 10 * minute, 100 * minute, 60.0 * minute + 0.5)
    # The run ended at 200 s: its final policy (learner.pt) is the curve's last point.
    save_learner(run / "checkpoints" / "learner.pt", 20, 2)
    end = {"wall_s": 200.0, "learner_steps": 30, "env_steps": 300}
    (run / "summary.json").write_text(json.dumps(end))
    curve = script("peers").evaluate(run, episodes=2, seed=1000)
    assert json.loads((run / "curve.json").read_text()) == curve
    assert [(c["wall_min"], c["env_steps"], c["episodes"]) for c in curve] == [
        (1.0, 100, 2), (2.0, 200, 2), (3.33, 300, 2)]  # fmt: skip
    assert curve[-1]["final"] is True and "final" not in curve[0]
    for c in curve:
        assert sum(c[f"{k}_rate"] for k in ("success", "collision", "timeout", "other")) == (
            pytest.approx(1.0))  # fmt: skip


@pytest.mark.parametrize("algo", ["rllib-ppo", "rllib-sac"])
def test_an_rllib_peer_trains_by_wall_time_and_its_checkpoints_are_scored(
    tmp_path: Path, algo: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    """RLlib lives in its own virtual environment (requirements/peers-rllib.txt): this test runs
    there (``pip install pytest`` in it) and is skipped where RLlib is not installed."""
    pytest.importorskip("ray.rllib.algorithms.ppo")
    out = tmp_path / algo
    cmd = [sys.executable, "experiments/peers.py", "train", "--algo", algo, "--problem",
           "navigation", "--minutes", "0.1", "--save-every-min", "0.05",
           "--out", str(out)]  # fmt: skip
    repo = Path(__file__).resolve().parents[2]
    done = children.run(cmd, cwd=repo, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr[-2000:]
    record = json.loads((out / "run.json").read_text())
    assert record["complete"] is True and record["num_env_runners"] == (os.cpu_count() or 1)
    # A PPO iteration (4,000 env steps) outlasts a 3 s mark: only the latest mark passed at an
    # iteration's end is saved, and the run ends on the budget's.
    marks = [s["wall_min"] for s in record["snapshots"]]
    assert marks[-1] == 0.1 and marks == sorted(set(marks))
    for snap in record["snapshots"]:
        assert snap["saved_at_min"] >= snap["wall_min"] and snap["env_steps"] > 0
    # As the docs' commands give it: a run folder relative to the working directory.
    monkeypatch.chdir(tmp_path)
    curve = script("peers").evaluate(Path(algo), episodes=1, seed=1000)
    assert [c["wall_min"] for c in curve] == marks
    if algo == "rllib-ppo":  # its Gaussian's std, and how much of what it samples is clipped
        points = script("peers").exploration(Path(algo), episodes=2)
        assert [p["wall_min"] for p in points] == marks
        assert all(p["policy_std"] > 0 and 0 <= p["clipped_share"] <= 1 for p in points)
        assert all(0 < p["action_std"] <= 1 for p in points)  # samples clipped to [-1, 1]
