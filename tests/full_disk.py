"""A real small disk for the disk-full tests: a tmpfs of a given size, mounted in a private mount
namespace (``unshare``) around one command, so nothing outside sees it and it goes away with
the command, even when a test is interrupted.

As root (CI) ``unshare -m`` does it; an unprivileged user gets the same from a user namespace
(``unshare -rm``). Where neither works, the tests that need it are skipped, saying why. The
test's ``probe`` function runs on the small disk and reports what it found in a file outside.
"""

from __future__ import annotations

import functools
import json
import os
import subprocess
import sys
import tempfile
from contextlib import suppress
from pathlib import Path
from typing import Any

import pytest

from robogym_ray import children

REPO = Path(__file__).resolve().parents[1]
_MOUNT = 'mount -t tmpfs -o "size=$1" tmpfs "$2" && shift 2 && exec "$@"'


@functools.cache
def _unshare() -> tuple[list[str] | None, str]:
    """The unshare command that can mount a tmpfs here, or None and why none can."""
    tries = [["unshare", "-m"]] if os.geteuid() == 0 else []
    tries.append(["unshare", "-rm"])
    why = "no unshare command"
    with tempfile.TemporaryDirectory() as mountpoint:
        for cmd in tries:
            try:
                done = children.run(
                    [*cmd, "sh", "-c", _MOUNT, "sh", "64k", mountpoint, "true"],
                    capture_output=True, text=True, timeout=30,
                )  # fmt: skip
            except (OSError, subprocess.TimeoutExpired) as exc:
                why = f"{' '.join(cmd)}: {exc}"
                continue
            if done.returncode == 0:
                return cmd, ""
            why = f"{' '.join(cmd)} + mount -t tmpfs: {done.stderr.strip()}"
    return None, why


def run_on_tmpfs(mountpoint: Path, size: str, probe: str, *args: str, timeout: float = 120) -> Any:
    """Calls ``probe`` (``module:function``) with ``args``, in a Python of its own (from the
    repository root) with a fresh tmpfs of ``size`` at ``mountpoint``; returns what it gave
    ``report``.

    Skips the test when no tmpfs can be mounted here (no root, no user namespaces)."""
    cmd, why = _unshare()
    if cmd is None:
        pytest.skip(f"a small real disk needs a tmpfs mount, and none works here ({why})")
    mountpoint.mkdir(parents=True, exist_ok=True)
    report = mountpoint.parent / f"{mountpoint.name}.report.json"  # outside the tmpfs
    env = {**os.environ, "PROBE_REPORT": str(report)}
    module, function = probe.split(":")
    code = f"import sys; from {module} import {function}; {function}(*sys.argv[1:])"
    done = children.run(
        [*cmd, "sh", "-c", _MOUNT, "sh", size, str(mountpoint), sys.executable, "-c", code,
         *args],
        cwd=REPO, env=env, capture_output=True, text=True, timeout=timeout,
    )  # fmt: skip
    assert report.exists(), f"the probe reported nothing (rc {done.returncode}):\n{done.stderr}"
    return json.loads(report.read_text())


def report(data: Any) -> None:
    """What a probe found, for ``run_on_tmpfs`` to return."""
    Path(os.environ["PROBE_REPORT"]).write_text(json.dumps(data))


def fill(directory: Path) -> None:
    """Writes a file into ``directory`` until its disk is full (ENOSPC), to the last byte."""
    with open(directory / "filler", "wb", buffering=0) as f:
        for chunk in (b"\0" * 65536, b"\0"):
            with suppress(OSError):
                while f.write(chunk):
                    pass


def tmp_files(directory: Path) -> list[str]:
    """Temporary files (``*.tmp*``) under ``directory``."""
    return sorted(str(p.relative_to(directory)) for p in directory.rglob("*.tmp*"))
