"""TensorBoard on a full disk (a real tmpfs, ``tests/full_disk.py``): ``RunLogger`` raises
nothing and prints no thread traceback; it keeps the error, naming the run directory, and sets
the run's stop event so the training loop ends the run with that one line."""

from __future__ import annotations

import contextlib
import io
import threading
from pathlib import Path

from tests.full_disk import fill, report, run_on_tmpfs


def _tensorboard_threads_done() -> None:
    for thread in threading.enumerate():
        if type(thread).__module__.startswith("tensorboard."):
            thread.join(timeout=10)


def probe(disk: str) -> None:
    from robogym_ray.training.logger import RunLogger

    disk_dir = Path(disk)
    out = {}
    stderr = io.StringIO()
    with contextlib.redirect_stderr(stderr):
        stop = threading.Event()
        logger = RunLogger(disk_dir / "run", total=100, progress=False, stop=stop)
        fill(disk_dir)
        for step in range(2000):
            logger.scalar("loss/critic", float(step), step)
        logger.write({"train/success_rate": 0.5}, 2000)
        logger.close()
        _tensorboard_threads_done()
        out["filled"] = {"error": str(logger.error), "stop": stop.is_set()}

        # A run that starts on a full disk: the event file cannot even be created.
        late_stop = threading.Event()
        late = RunLogger(disk_dir / "late", total=100, progress=False, stop=late_stop)
        late.scalar("loss/critic", 1.0, 1)
        late.close()
        _tensorboard_threads_done()
        out["full_at_start"] = {"error": str(late.error), "stop": late_stop.is_set()}
    out["stderr"] = stderr.getvalue()
    report(out)


def test_tensorboard_on_a_full_disk_stops_the_run_without_a_traceback(tmp_path: Path) -> None:
    disk = tmp_path / "disk"
    out = run_on_tmpfs(disk, "1m", f"{__name__}:probe", str(disk))
    assert out["filled"] == {
        "error": f"cannot write TensorBoard events in {disk / 'run'}: no space left on device",
        "stop": True,
    }
    assert out["full_at_start"]["stop"] is True
    assert out["full_at_start"]["error"].endswith("no space left on device")
    assert "Traceback" not in out["stderr"] and "Exception in thread" not in out["stderr"]
