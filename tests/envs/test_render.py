"""Frames: every env renders, the robot appears where its state says, videos, human windows."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import robogym_ray  # noqa: F401 - registers the ids
from robogym_ray import children
from robogym_ray.envs import SIM_ENV_IDS
from robogym_ray.envs.render import RenderConfig
from robogym_ray.envs.render.mir100 import ROBOT
from robogym_ray.envs.render.ur import TABLE, TOOL, Stand, draw_ur, stand_of
from robogym_ray.errors import ConfigError, RenderError

NAV = "RoboGymRay/ObstacleAvoidanceMir100Sim-v0"
UR10 = "RoboGymRay/EndEffectorPositioningUR10Sim-v0"
ISAAC_UR10 = "RoboGymRay/IsaacReachUR10Sim-v0"


def centroid(frame: np.ndarray, color: tuple[int, int, int]) -> np.ndarray:
    """(column, row) centre of the pixels of exactly ``color``; fails when there are none."""
    rows, cols = np.nonzero(np.all(frame == np.array(color, np.uint8), axis=2))
    assert rows.size > 20, f"no region of colour {color} in the frame"
    return np.array([cols.mean(), rows.mean()])


@pytest.mark.parametrize("env_id", SIM_ENV_IDS)
def test_every_sim_env_renders_a_non_blank_frame(env_id: str) -> None:
    env = gym.make(env_id, render_mode="rgb_array")
    try:
        env.reset(seed=3)
        env.step(env.action_space.sample())
        frame = env.render()
        assert frame.shape == (480, 640, 3) and frame.dtype == np.uint8
        drawn = (~np.all(frame == frame[-1, -1], axis=2)).sum()  # not the background colour
        assert drawn > 1000 and len(np.unique(frame.reshape(-1, 3), axis=0)) > 5
    finally:
        env.close()


def test_mir100_footprint_moves_forward_in_the_image_after_a_forward_twist() -> None:
    cfg = RenderConfig(width=320, height=240)
    env = gym.make(NAV, render_mode="rgb_array", render_config=cfg)
    try:
        # Heading +x (right in the image), clear of the cubes, target far to the right.
        options = {
            "start_pose": [-2.0, -2.5, 0.0],
            "target_pose": [2.0, -2.5, 0.0],
            "obstacles": [[-2.0, 1.0, 0.0], [0.0, 1.0, 0.0], [2.0, 1.0, 0.0]],
        }
        env.reset(seed=0, options=options)
        before = centroid(env.render(), ROBOT)
        for _ in range(10):
            env.step(np.array([1.0, 0.0], np.float32))
        after = centroid(env.render(), ROBOT)
        moved = env.unwrapped._last_msg.state[3] - (-2.0)  # metres along x, from the state
        px_per_m = 240 / 9.0  # TopDownCamera(): the shorter side spans 9 m
        assert moved > 0.3
        assert after[0] - before[0] == pytest.approx(moved * px_per_m, abs=2.0)
        assert abs(after[1] - before[1]) < 2.0
    finally:
        env.close()


def test_ur_end_effector_region_moves_after_a_joint_move() -> None:
    env = gym.make(UR10, render_mode="rgb_array")
    try:
        env.reset(seed=0, options={"joint_positions": [0.0, -2.5, 1.5, 0.0, -1.4, 0.0]})
        before = centroid(env.render(), TOOL)
        base = np.zeros(env.action_space.shape, np.float32)
        base[0] = 0.25  # the base joint to +pi/2 (normalised by 2 pi): the arm swings round
        for _ in range(30):
            env.step(base)
        after = centroid(env.render(), TOOL)
        assert np.linalg.norm(after - before) > 40
    finally:
        env.close()


def test_isaac_reach_ur10_stands_on_the_demo_table_of_its_world() -> None:
    env = gym.make(ISAAC_UR10, render_mode="rgb_array")
    try:
        env.reset(seed=0)
        frame = env.render()
        assert frame.shape == (480, 640, 3) and frame.dtype == np.uint8
        assert (~np.all(frame == frame[-1, -1], axis=2)).sum() > 1000
        task = env.unwrapped
        stand = stand_of(task.server_spec())
        # The isaactabletop world: base_link on the table's top (z:=0.0), its foot 1 m below.
        (table,) = stand.tables
        assert table.centre[2] + table.half_extents[2] == pytest.approx(0.0)
        assert stand.ground_z == pytest.approx(-1.0) and stand.support_z() == pytest.approx(0.0)
        drawn = draw_ur("ur10", task.joints(task._last_msg), RenderConfig(), stand=stand)
        assert np.all(drawn == np.array(TABLE, np.uint8), axis=2).sum() > 5000
    finally:
        env.close()


def test_the_default_stand_is_the_ground_a_tenth_below_base_link() -> None:
    # The positioning env's launch (empty world, default base height) is the default stand,
    # so its frames (docs/img/ur10.png) are those drawn before stands existed.
    env = gym.make(UR10)
    try:
        assert stand_of(env.unwrapped.server_spec()) == Stand()
        assert Stand().support_z() == pytest.approx(-0.1)
    finally:
        env.close()


def test_render_before_reset_and_bad_modes_are_refused() -> None:
    with pytest.raises(ConfigError, match="render_mode 'video'"):
        gym.make(NAV, render_mode="video", disable_env_checker=True)
    env = gym.make(NAV, render_mode="rgb_array", disable_env_checker=True)
    with pytest.raises(gym.error.ResetNeeded):
        env.unwrapped.render()
    env.close()
    with pytest.raises(ConfigError, match="width"):
        RenderConfig(width=0)


def test_human_mode_without_a_display_fails_at_construction(monkeypatch) -> None:
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    with pytest.raises(RenderError, match="rgb_array"):
        gym.make(NAV, render_mode="human")


def test_a_rob_env_on_an_emulated_robot_renders(serve_subprocess) -> None:
    address = serve_subprocess("mir100", "--scene", "lab_6x8", "--emulate-hardware")
    env = gym.make(
        "RoboGymRay/ObstacleAvoidanceMir100Rob-v0", rs_address=address, render_mode="rgb_array"
    )
    try:
        env.reset(seed=0)
        frame = env.render()
        centroid(frame, ROBOT)
        # The laser returns of the real (emulated) scene are drawn: walls and cubes.
        assert np.all(frame == np.array((220, 40, 40), np.uint8), axis=2).sum() > 200
    finally:
        env.close()


def test_record_video_writes_a_playable_mp4(tmp_path: Path) -> None:
    imageio_ffmpeg = pytest.importorskip("imageio_ffmpeg")
    pytest.importorskip("moviepy")
    env = gym.make(NAV, render_mode="rgb_array", render_config=RenderConfig(320, 240))
    env = gym.wrappers.RecordVideo(env, str(tmp_path), episode_trigger=lambda _: True)
    env.reset(seed=1)
    steps = 0
    for _ in range(25):
        _, _, terminated, truncated, _ = env.step(np.array([0.5, 0.1], np.float32))
        steps += 1
        if terminated or truncated:
            break
    env.close()
    (video,) = tmp_path.glob("*.mp4")
    reader = imageio_ffmpeg.read_frames(str(video))
    meta = next(reader)
    frames = sum(1 for _ in reader)
    assert meta["size"] == (320, 240) and frames == steps + 1  # the reset frame, then each step


def test_human_mode_shows_a_window_under_a_real_x_server(x_display: str, tmp_path: Path) -> None:
    pytest.importorskip("pygame")
    from PIL import ImageGrab

    script = tmp_path / "watch.py"
    script.write_text(
        "import sys, time, gymnasium as gym, numpy as np, robogym_ray\n"
        f"env = gym.make({NAV!r}, render_mode='human')\n"
        "env.reset(seed=0)\n"
        "for _ in range(5):\n"
        "    env.step(np.array([0.5, 0.0], np.float32))\n"
        "print('shown', flush=True)\n"
        "sys.stdin.readline()\n"  # the window stays up until the test has its screenshot
        "env.close()\n"
    )
    environ = {**os.environ, "DISPLAY": x_display, "SDL_AUDIODRIVER": "dummy"}
    proc = children.popen(
        [sys.executable, str(script)], stdin=subprocess.PIPE, stdout=subprocess.PIPE,
        env=environ, text=True,
    )  # fmt: skip
    try:
        assert proc.stdout is not None and proc.stdout.readline().strip() == "shown"
        if shutil.which("xwininfo"):
            tree = children.run(
                ["xwininfo", "-root", "-tree", "-display", x_display],
                capture_output=True, text=True, check=True,
            ).stdout  # fmt: skip
            assert "ObstacleAvoidanceMir100" in tree
        shot = np.asarray(ImageGrab.grab(xdisplay=x_display).convert("RGB"))
        window = shot[:480, :640]
        assert window.std() > 10 and np.all(window == ROBOT, axis=2).sum() > 50
    finally:
        proc.communicate("\n", timeout=30)
