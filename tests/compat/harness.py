"""Processes of both sides: our ``robogym-ray`` commands and robo-gym's scripts in its venv.

Our side runs exactly as a user would start it (``robogym-ray serve`` / ``robogym-ray manager``
subprocesses of this interpreter); robo-gym's side runs scripts from ``robo_gym_side/`` with the
venv's interpreter and reports what robo-gym's objects returned as JSON.
"""

from __future__ import annotations

import json
import os
import selectors
import signal
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest

from robogym_ray import children

SCRIPTS = Path(__file__).parent / "robo_gym_side"


@dataclass
class Started:
    """A ``robogym-ray`` command that printed ``listening on HOST:PORT``."""

    proc: subprocess.Popen[str]
    address: str
    log: Path
    """Its stderr (robot-server and Ray logs), kept until the session ends."""


def start_cli(args: list[str], log: Path, timeout: float, env: dict[str, str]) -> Started:
    """Run ``robogym-ray ARGS`` and wait for its ``listening on`` line.

    Raises:
        pytest.fail.Exception: it exited or stayed silent for ``timeout`` seconds.
    """
    with log.open("w") as err:
        proc = children.popen(
            [sys.executable, "-m", "robogym_ray.cli", *args],
            stdout=subprocess.PIPE,
            stderr=err,
            text=True,
            env=env,
        )
    assert proc.stdout is not None
    selector = selectors.DefaultSelector()
    selector.register(proc.stdout, selectors.EVENT_READ)
    deadline = time.monotonic() + timeout
    while (left := deadline - time.monotonic()) > 0 and selector.select(timeout=left):
        line = proc.stdout.readline()
        if not line:
            break
        if line.startswith("listening on "):
            return Started(proc, line.removeprefix("listening on ").strip(), log)
    stop(proc)
    pytest.fail(
        f"robogym-ray {' '.join(args)} did not print 'listening on' within {timeout:.0f} s "
        f"(rc {proc.returncode}); stderr tail:\n{log.read_text(errors='replace')[-3000:]}"
    )


def stop(proc: subprocess.Popen[str], timeout: float = 60.0) -> None:
    """SIGTERM (both commands clean up on it), then SIGKILL if it does not exit in time."""
    if proc.poll() is None:
        os.kill(proc.pid, signal.SIGTERM)
        try:
            proc.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            os.kill(proc.pid, signal.SIGKILL)
            proc.wait()
    if proc.stdout is not None:
        proc.stdout.close()


def run_robo_gym(python: Path, script: str, *args: str, timeout: float = 180) -> dict[str, Any]:
    """Run ``robo_gym_side/<script>`` in the robo-gym venv; returns the JSON it wrote.

    The script gets ``--out FILE`` after ``args``; a non-zero exit fails the test with its output
    (robo-gym's exceptions, e.g. InvalidStateError, surface here).
    """
    with tempfile.NamedTemporaryFile(suffix=".json", delete=False) as out:
        out_path = Path(out.name)
    try:
        done = children.run(
            [str(python), str(SCRIPTS / script), *args, "--out", str(out_path)],
            capture_output=True,
            text=True,
            timeout=timeout,
            check=False,
            # Nothing of our environment (PYTHONPATH, our protobuf) may reach robo-gym's side.
            env={k: v for k, v in os.environ.items() if not k.startswith("PYTHON")},
            cwd=tempfile.gettempdir(),
        )
        if done.returncode != 0:
            pytest.fail(
                f"robo-gym side {script} {' '.join(args)} failed (rc {done.returncode}):\n"
                f"--- stdout ---\n{done.stdout[-3000:]}\n--- stderr ---\n{done.stderr[-5000:]}"
            )
        return json.loads(out_path.read_text())
    finally:
        out_path.unlink(missing_ok=True)
