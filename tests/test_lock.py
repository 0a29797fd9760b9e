"""The lock of tested versions covers what pyproject.toml asks for, and CI installs as the README.

A fresh install gets the newest release inside each range; the lock (requirements/lock.txt,
refreshed by requirements/refresh-lock) pins what CI tested, and the README installs with it as
constraints. These tests fail when the three drift apart.
"""

from __future__ import annotations

import re
import sys
from pathlib import Path

import pytest
from packaging.requirements import Requirement
from packaging.utils import canonicalize_name
from packaging.version import Version

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - the test extra installs tomli on 3.10
    import tomli as tomllib

ROOT = Path(__file__).resolve().parents[1]
PYTHONS = ("3.10", "3.11", "3.12")


def _declared() -> list[Requirement]:
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    deps = list(project["dependencies"])
    for extra in project["optional-dependencies"].values():
        deps += extra
    return [Requirement(d) for d in deps]


def _linux(python: str) -> dict[str, str]:
    return {
        "python_version": python,
        "python_full_version": f"{python}.0",
        "sys_platform": "linux",
        "platform_system": "Linux",
        "platform_machine": "x86_64",
        "os_name": "posix",
        "implementation_name": "cpython",
        "platform_python_implementation": "CPython",
    }


def _locked(python: str) -> dict[str, Version]:
    """Package -> pinned version among the lock's lines that apply on Linux with ``python``."""
    pins: dict[str, Version] = {}
    for line in (ROOT / "requirements" / "lock.txt").read_text().splitlines():
        if not line or line[0] in "# ":
            continue
        req = Requirement(line)
        if req.marker is None or req.marker.evaluate(_linux(python)):
            (spec,) = req.specifier
            assert spec.operator == "==", f"lock.txt: {line!r} is not a pin"
            pins[canonicalize_name(req.name)] = Version(spec.version)
    return pins


@pytest.mark.parametrize("python", PYTHONS)
def test_the_lock_pins_every_declared_dependency_inside_its_range(python: str) -> None:
    pins = _locked(python)
    for req in _declared():
        if req.marker is not None and not req.marker.evaluate(_linux(python)):
            continue
        name = canonicalize_name(req.name)
        assert name in pins, (
            f"pyproject.toml names {req.name} but requirements/lock.txt has no pin for it on "
            f"Python {python}: run `bash requirements/refresh-lock`"
        )
        assert req.specifier.contains(pins[name], prereleases=True), (
            f"lock.txt pins {name}=={pins[name]} outside pyproject.toml's {req}: refresh the lock"
        )


def test_every_range_has_an_upper_bound() -> None:
    for req in _declared():
        ops = {s.operator for s in req.specifier}
        assert ops & {"<", "<=", "==", "~="}, f"pyproject.toml: {req} has no upper bound"


def test_the_lock_pins_torch_as_the_readme_installs_it() -> None:
    readme = (ROOT / "README.md").read_text()
    pinned = (ROOT / "requirements" / "torch.txt").read_text().split("torch==")[1].split()[0]
    assert f"pip install torch=={pinned} -c requirements/lock.txt" in readme
    for python in PYTHONS:
        assert _locked(python)["torch"] == Version(pinned)


def _install_command(text: str) -> str:
    found = re.search(
        r"^(pip install torch==\S+ -c requirements/lock\.txt && pip install .*?"
        r"-c requirements/lock\.txt)",
        text,
        re.MULTILINE,
    )
    assert found, "no install command with the lock as constraints"
    return found.group(1)


def test_ci_installs_exactly_as_the_readme_says_in_its_own_venv() -> None:
    ci = (ROOT / ".ci" / "run").read_text()
    readme_install = _install_command((ROOT / "README.md").read_text())
    assert _install_command(ci) == readme_install
    # Its own virtual environment, made before the install, and the README's test command.
    assert ci.index("python3 -m venv") < ci.index("/bin/activate") < ci.index(readme_install)
    assert ci.rstrip().endswith("python3 -m pytest -q")
    assert "python3 -m pytest -q" in (ROOT / "README.md").read_text()
