"""A disk that fills up during a real ``robogym-ray train`` (its own embedded Ray, on a real
tmpfs: ``tests/full_disk.py``): the run stops with one ``error:`` line naming the file that
could not be written and why, exit code 2, no temporary files, the last good checkpoint intact
and loadable, and ``summary.json`` when there is room for it (the line says when there is not).
"""

from __future__ import annotations

import concurrent.futures
import contextlib
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import pytest

from robogym_ray import children
from tests.full_disk import report, run_on_tmpfs, tmp_files

pytestmark = [pytest.mark.ray, pytest.mark.slow]

# Learner steps from the first few hundred env steps, so checkpoints come early and often.
D4PG = {"d4pg": {"min_replay_size": 256, "batch_size": 64}}


def _keep_free(disk: Path, room: int, serial: list[int]) -> None:
    """Fills ``disk`` until at most ``room`` bytes are free (a new filler file each time)."""
    st = os.statvfs(disk)
    extra = st.f_bavail * st.f_frsize - room
    if extra <= 0:
        return
    serial[0] += 1
    with open(disk / f"filler-{serial[0]}", "wb", buffering=0) as f:
        for chunk in (b"\0" * min(extra, 1 << 20), b"\0"):
            with contextlib.suppress(OSError):
                while extra > 0:
                    extra -= f.write(chunk[:extra])


def probe(disk: str, config: str, room_fraction: str) -> None:
    """Runs on the tmpfs: a training that, once its first checkpoint is there, finds only
    ``room_fraction`` of a checkpoint free on its disk for the rest of the run."""
    from robogym_ray.learner import checkpoint

    disk_dir = Path(disk)
    good = disk_dir / "run" / "checkpoints" / checkpoint.CHECKPOINT_NAME
    ray_tmp = tempfile.mkdtemp(prefix="rgf", dir="/tmp")  # short: Unix socket paths
    cmd = [
        sys.executable, "-m", "robogym_ray.cli", "train", "--config", config,
        "--task", "navigation", "--workers", "1", "--envs-per-worker", "1",
        "--total-steps", "20000", "--max-wall-s", "150", "--checkpoint-every", "20",
        "--logdir", disk, "--run-name", "run", "--no-progress", "--no-evaluator",
        "--num-cpus", "2",
    ]  # fmt: skip
    started = time.monotonic()
    proc = children.popen(
        cmd, env={**os.environ, "RAY_TMPDIR": ray_tmp, "RAY_AUTH_MODE": "disabled"},
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )  # fmt: skip
    serial = [0]
    try:
        # Kept full while the run goes on: space a failed write frees is taken again at once.
        while proc.poll() is None:
            if good.exists():
                _keep_free(disk_dir, int(good.stat().st_size * float(room_fraction)), serial)
            time.sleep(0.02)
        stdout, stderr = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
        shutil.rmtree(ray_tmp, ignore_errors=True)
    summary = disk_dir / "run" / "summary.json"
    report({
        "rc": proc.returncode, "stderr": stderr, "stdout": stdout,
        "wall_s": time.monotonic() - started,
        "tmp": tmp_files(disk_dir),
        "checkpoint_steps": int(checkpoint.read(good)["num_steps"]) if good.exists() else None,
        "summary": json.loads(summary.read_text()) if summary.exists() else None,
    })  # fmt: skip


def _train_on_a_filling_disk(root: Path, room_fraction: float) -> tuple[dict[str, Any], Path]:
    config = root / "d4pg.json"
    config.write_text(json.dumps(D4PG))
    disk = root / "disk"
    out = run_on_tmpfs(
        disk, "64m", f"{__name__}:probe", str(disk), str(config), str(room_fraction), timeout=240
    )
    assert out["rc"] == 2, out["stdout"][-2000:] + out["stderr"][-4000:]
    assert "Traceback" not in out["stderr"], out["stderr"][-4000:]
    assert out["tmp"] == []  # no half-written checkpoint, replay or summary left behind
    assert out["checkpoint_steps"] and out["checkpoint_steps"] > 0  # the last good one loads
    return out, disk / "run"


ROOMS = {"half": 0.5, "none": 0.0}
"""Room left after the first checkpoint, as a fraction of one: half (the next checkpoint fails,
the summary fits) and none (the summary does not fit either)."""


@pytest.fixture(scope="module")
def filled(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    """{room: (what the probe saw, the run folder)}: the two trainings run side by side, each
    with its own disk and Ray (they stop on a failed write, not on time)."""
    with concurrent.futures.ThreadPoolExecutor(len(ROOMS)) as pool:
        runs = {name: pool.submit(_train_on_a_filling_disk, tmp_path_factory.mktemp(name), room)
                for name, room in ROOMS.items()}  # fmt: skip
        return {name: run.result() for name, run in runs.items()}


def test_a_full_disk_stops_the_run_in_one_line_and_the_summary_is_written_when_it_fits(
    filled: dict[str, Any],
) -> None:
    # Room for half a checkpoint: the next checkpoint fails; the summary fits.
    out, run = filled["half"]
    last = out["stderr"].strip().splitlines()[-1]
    learner_pt = run / "checkpoints" / "learner.pt"
    assert last.startswith(f"error: cannot write learner checkpoint {learner_pt}: ")
    assert "no space left on device" in last
    assert f"the last good checkpoint is kept: {learner_pt}" in last
    assert f"summary: {run / 'summary.json'}" in last
    summary = out["summary"]
    assert summary is not None and summary["checkpoint"] == str(learner_pt)
    assert summary["error"].startswith("cannot write learner checkpoint")
    assert summary["env_steps"] < 20000  # stopped at the failure, not retried to the end


def test_a_disk_with_no_room_for_the_summary_says_so_in_the_same_line(
    filled: dict[str, Any],
) -> None:
    out, run = filled["none"]
    last = out["stderr"].strip().splitlines()[-1]
    assert last.startswith("error: cannot write ")
    assert "no space left on device" in last
    assert f"cannot write summary {run / 'summary.json'}: no space left on device" in last
    assert out["summary"] is None
