"""The zip and metadata work of ``benchmarks/device_kit.sh``, run by its build venv's Python 3.12
(it has ``packaging``); device_kit.sh says why the kit is built this way. One subcommand a call:

    locked LOCK NAME...                       NAME==VERSION from the lock, one a line
    repack WHEEL OUT_DIR [GLOB...]            the wheel into OUT_DIR: GLOB members left out, ELF
                                              files stripped, stored uncompressed
    check STAGE PYPROJECT NODE_HAS LEFT_OUT   fails unless each requirement is in STAGE or NODE_HAS
    tree ROOT                                 the working tree's bytes, as a device call counts them
"""

from __future__ import annotations

import base64
import csv
import email.parser
import fnmatch
import hashlib
import io
import os
import subprocess
import sys
import tempfile
import zipfile
from collections.abc import Callable
from pathlib import Path

import tomllib
from packaging.markers import Marker
from packaging.requirements import Requirement
from packaging.utils import canonicalize_name


def locked(lock: str, *names: str) -> None:
    """Prints NAME==VERSION from the lock for each name, the line whose marker holds here."""
    pins = {}
    for line in Path(lock).read_text().splitlines():
        if not line or line[0] in "# ":
            continue
        req, _, marker = line.partition(";")
        name, _, version = req.strip().partition("==")
        if not marker.strip() or Marker(marker).evaluate():
            pins[canonicalize_name(name)] = f"{name}=={version}"
    for name in names:
        if canonicalize_name(name) not in pins:
            sys.exit(f"{name}: not in {lock}")
        print(pins[canonicalize_name(name)])


def stripped(data: bytes) -> bytes:
    """An ELF file's bytes without the symbols it does not need (most of a shared object's size)."""
    with tempfile.NamedTemporaryFile() as f:
        f.write(data)
        f.flush()
        subprocess.run(["strip", "--strip-unneeded", f.name], check=True)
        return Path(f.name).read_bytes()


def repack(src: str, out_dir: str, *drop: str) -> None:
    """Writes wheel SRC into OUT_DIR: members matching a DROP glob left out, ELF files stripped,
    stored uncompressed, RECORD rewritten (hashes and sizes of what is in it now)."""
    dst = Path(out_dir) / Path(src).name
    rows: list[tuple[str, str, int | str]] = []
    dropped, saved = 0, 0
    with zipfile.ZipFile(src) as zin, zipfile.ZipFile(f"{dst}.part", "w") as zout:
        record = next(n for n in zin.namelist() if n.endswith(".dist-info/RECORD"))
        for info in zin.infolist():
            name = info.filename
            if name == record or name.endswith("/"):
                continue
            if any(fnmatch.fnmatch(name, pattern) for pattern in drop):
                dropped += info.file_size
                continue
            data = zin.read(info)
            if data[:4] == b"\x7fELF":
                new = stripped(data)
                saved += len(data) - len(new)
                data = new
            member = zipfile.ZipInfo(name, info.date_time)
            member.external_attr = info.external_attr  # the executables' modes (gcs_server)
            zout.writestr(member, data)
            digest = base64.urlsafe_b64encode(hashlib.sha256(data).digest()).rstrip(b"=")
            rows.append((name, f"sha256={digest.decode()}", len(data)))
        rows.append((record, "", ""))
        text = io.StringIO()
        csv.writer(text, lineterminator="\n").writerows(rows)
        zout.writestr(zipfile.ZipInfo(record, (1980, 1, 1, 0, 0, 0)), text.getvalue())
    os.replace(f"{dst}.part", dst)
    print(f"  {dst.name}: {dropped / 1e6:.1f} MB dropped, {saved / 1e6:.1f} MB stripped")


def check(stage: str, pyproject: str, node_has: str, left_out: str) -> None:
    """Fails unless each requirement of the project and of the kit's wheels (markers taken for
    this interpreter: CPython 3.12 on Linux; a wheel's extras those the project names, less
    LEFT_OUT) is in the kit or on the node."""
    config = tomllib.loads(Path(pyproject).read_text())
    project = [Requirement(r) for r in config["project"]["dependencies"]]
    left = {canonicalize_name(r.name): r.extras for r in map(Requirement, left_out.split())}
    extras = {
        canonicalize_name(r.name): r.extras - left.get(canonicalize_name(r.name), set())
        for r in project
    }
    kit: set[str] = set()
    needs = [("robogym-ray", {""}, r) for r in project]
    for wheel in sorted(Path(stage).glob("*.whl")):
        with zipfile.ZipFile(wheel) as z:
            meta = next(n for n in z.namelist() if n.endswith(".dist-info/METADATA"))
            msg = email.parser.Parser().parsestr(z.read(meta).decode())
        name = canonicalize_name(msg["Name"])
        kit.add(name)
        wanted = {""} | extras.get(name, set())
        needs += [(msg["Name"], wanted, Requirement(r)) for r in msg.get_all("Requires-Dist") or []]
    applying = [
        (who, r)
        for who, wanted, r in needs
        if r.marker is None or any(r.marker.evaluate({"extra": e}) for e in wanted)
    ]
    have = kit | {canonicalize_name(n) for n in node_has.split()}
    missing = {
        f"{r.name} (for {who})" for who, r in applying if canonicalize_name(r.name) not in have
    }
    if missing:
        sys.exit("neither in the kit nor on the node: " + ", ".join(sorted(missing)))
    print(f"requirements: all {len(applying)} are in the kit or on the node; left out: {left_out}")


def tree(root: str) -> None:
    """The working tree's bytes as a device call counts them: tracked and untracked-not-ignored."""
    listed = subprocess.run(
        ["git", "-C", root, "ls-files", "-co", "--exclude-standard", "-z"],
        check=True,
        capture_output=True,
    )
    paths = [os.path.join(root.encode(), n) for n in listed.stdout.split(b"\0") if n]
    print(sum(os.lstat(p).st_size for p in paths if os.path.lexists(p)))


COMMANDS: dict[str, Callable[..., None]] = {
    "locked": locked,
    "repack": repack,
    "check": check,
    "tree": tree,
}


def main(argv: list[str]) -> None:
    """Runs the subcommand ``argv[0]`` with the rest as its arguments."""
    if not argv or argv[0] not in COMMANDS:
        sys.exit(f"usage: device_kit.py {{{','.join(COMMANDS)}}} ARG... (got {argv[:1]})")
    COMMANDS[argv[0]](*argv[1:])


if __name__ == "__main__":
    main(sys.argv[1:])
