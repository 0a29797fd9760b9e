"""``robogym-ray evaluate --video`` and ``--paths``: one MP4 per filmed episode, paths kept."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest

from robogym_ray import children

NAV = "RoboGymRay/ObstacleAvoidanceMir100Sim-v0"


@pytest.fixture
def untrained_checkpoint(tmp_path: Path) -> Path:
    from robogym_ray.learner.config import D4PGConfig
    from robogym_ray.learner.learner import D4PGLearner

    path = tmp_path / "learner.pt"
    cfg = D4PGConfig(policy_hidden=(16,), critic_hidden=(16,))
    D4PGLearner(cfg, obs_dim=20, act_dim=2).save(path)
    return path


def test_evaluate_writes_one_video_per_requested_episode_and_paths(
    untrained_checkpoint: Path, tmp_path: Path
) -> None:
    imageio_ffmpeg = pytest.importorskip("imageio_ffmpeg")
    videos, out = tmp_path / "videos", tmp_path / "eval"
    cmd = [
        sys.executable, "-m", "robogym_ray.cli", "evaluate", str(untrained_checkpoint),
        "--env-id", NAV, "--episodes", "3", "--max-steps", "12", "--seed", "50",
        "--video", str(videos), "--video-episodes", "2", "--paths", "--out", str(out),
    ]  # fmt: skip
    done = children.run(cmd, capture_output=True, text=True, timeout=240)
    assert done.returncode == 0, done.stderr[-2000:]
    episodes = json.loads((out / "evaluation.json").read_text())["episodes"]
    files = sorted(videos.glob("*.mp4"))
    assert [f.name for f in files] == [
        f"episode-{e['index']:03d}-seed-{e['seed']}-{e['final_status']}.mp4" for e in episodes[:2]
    ]
    for video, episode in zip(files, episodes, strict=False):
        reader = imageio_ffmpeg.read_frames(str(video))
        assert next(reader)["size"] == (640, 480)
        assert sum(1 for _ in reader) == episode["length"] + 1  # reset frame + one per step
    for episode in episodes:  # x, y after reset and after each step
        assert len(episode["path"]) == episode["length"] + 1
        assert all(len(xy) == 2 for xy in episode["path"])
    for episode in episodes:  # the cubes this episode placed: x, y, yaw of each
        assert np.asarray(episode["obstacles"]).shape == (3, 3)
    # experiments/figures.py draws these paths over the lab, in each outcome's colour.
    pytest.importorskip("matplotlib")
    from PIL import Image

    from tests.experiments.test_scripts import script

    figure = script("figures").plot_paths(out / "evaluation.json", tmp_path / "paths.png")
    pixels = np.asarray(Image.open(figure).convert("RGB")).reshape(-1, 3).astype(int)
    tab = {"success": (44, 160, 44), "collision": (214, 39, 40),
           "max_steps_exceeded": (255, 127, 14)}  # fmt: skip
    for status in {e["final_status"] for e in episodes}:
        assert (np.abs(pixels - tab[status]).sum(axis=1) < 30).sum() > 50, status
