"""A separate virtualenv holding robo-gym's own, unmodified client stack (spec a.1, f).

robo-gym 2.0.1 needs protobuf 3.20.x, which cannot share an interpreter with our protobuf 7
generated code, so its client runs in its own venv, built once and cached under
``$XDG_CACHE_HOME/robogym-ray/robo-gym-venv/<key>`` (``~/.cache`` by default;
``ROBOGYM_RAY_COMPAT_CACHE`` overrides the parent folder). The key hashes the pins and the base
interpreter, so changing a pin builds a new venv and reruns reuse the old one.

All of robo-gym's dependencies install from PyPI as they are (no ``--no-deps`` needed):
``gymnasium, robo-gym-server-modules, numpy, scipy, pyyaml`` for robo-gym and
``grpcio, protobuf>=3.20,<3.21, libtmux, pyyaml`` for robo-gym-server-modules (libtmux is only
imported by the reference manager's server side, never by the clients used here).
"""

from __future__ import annotations

import hashlib
import os
import re
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import pytest

from robogym_ray import children

PINS: tuple[str, ...] = (
    "robo-gym==2.0.1",
    "robo-gym-server-modules==0.3.0.1",
    "protobuf==3.20.3",
    # The versions the spec's "(verified)" runs used; robo-gym leaves them unpinned.
    "grpcio==1.85.1",
    "gymnasium==1.4.0",
    "numpy==2.4.6",
    "scipy==1.17.1",
    "pyyaml==6.0.3",
)
READY = "robogym-ray-ready.txt"
"""Written last, after the import check: a folder without it is an interrupted build."""

# What pip prints when a pinned distribution cannot be had from the configured indexes (also
# what it ends with when no index is reachable at all). Any other failure is a test failure.
_UNAVAILABLE = re.compile(
    r"(No matching distribution found for \S+|"
    r"Could not find a version that satisfies the requirement \S+)"
)
_IMPORT_CHECK = (
    "import google.protobuf, robo_gym, robo_gym_server_modules.robot_server.client, "
    "robo_gym_server_modules.server_manager.client; print(google.protobuf.__version__)"
)


def cache_root() -> Path:
    override = os.environ.get("ROBOGYM_RAY_COMPAT_CACHE")
    if override:
        return Path(override)
    base = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache")
    return base / "robogym-ray" / "robo-gym-venv"


def venv_key() -> str:
    text = "\n".join((*PINS, sys.version, sys.base_prefix))
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def venv_python(venv: Path) -> Path:
    return venv / ("Scripts/python.exe" if os.name == "nt" else "bin/python")


def _run(cmd: list[str], timeout: float) -> subprocess.CompletedProcess[str]:
    return children.run(cmd, capture_output=True, text=True, timeout=timeout, check=False)


def _build(venv: Path) -> None:
    """Create ``venv`` and install the pins into it; skip or fail the test on errors."""
    made = _run([sys.executable, "-m", "venv", str(venv)], timeout=300)
    if made.returncode != 0:
        pytest.fail(f"python -m venv failed (rc {made.returncode}):\n{made.stderr[-3000:]}")
    # The venv's own pip, not ours: nothing of the main environment may leak into it.
    pip = [str(venv_python(venv)), "-m", "pip", "install", "--disable-pip-version-check"]
    installed = _run([*pip, "--retries", "2", *PINS], timeout=900)
    if installed.returncode != 0:
        output = installed.stdout + installed.stderr
        missing = _UNAVAILABLE.search(output)
        if missing:
            pytest.skip(
                "robo-gym's own client stack cannot be installed here, so wire compatibility "
                f"with it is not checked: pip says '{missing.group(0)}' (pins: {', '.join(PINS)})"
            )
        pytest.fail(
            f"pip install {' '.join(PINS)} failed (rc {installed.returncode}):\n{output[-4000:]}"
        )
    check = _run([str(venv_python(venv)), "-c", _IMPORT_CHECK], timeout=120)
    if check.returncode != 0 or not check.stdout.strip().startswith("3.20."):
        pytest.fail(f"robo-gym venv import check failed:\n{check.stdout}{check.stderr[-3000:]}")
    (venv / READY).write_text("\n".join(PINS) + "\n")


def ensure_venv() -> Path:
    """The python of a ready robo-gym venv, building it first if the cache has none.

    Built in a sibling temporary folder and renamed into place, so concurrent or interrupted
    runs never see a half-built venv. Falls back to a temporary folder if the cache folder is
    not writable.
    """
    root = cache_root()
    try:
        root.mkdir(parents=True, exist_ok=True)
    except OSError:
        root = Path(tempfile.mkdtemp(prefix="robo-gym-venv-"))
    venv = root / venv_key()
    if (venv / READY).is_file():
        return venv_python(venv)
    building = Path(tempfile.mkdtemp(prefix=f"{venv.name}.building-", dir=root))
    try:
        _build(building)
        if venv.exists():  # an unfinished earlier build, or a concurrent run finished first
            if (venv / READY).is_file():
                return venv_python(venv)
            shutil.rmtree(venv)
        building.rename(venv)
    finally:
        if building.exists():
            shutil.rmtree(building, ignore_errors=True)
    return venv_python(venv)
