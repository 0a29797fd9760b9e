"""Regenerate the committed gRPC code from the .proto files.

Usage: ``python -m robogym_ray.protocol.regen [OUT_DIR]`` (default: this package's directory).
Imports in the generated ``*_pb2_grpc.py`` are rewritten to package-relative form so the modules
work from inside ``robogym_ray.protocol``.
"""

from __future__ import annotations

import re
import sys
from pathlib import Path

PROTO_DIR = Path(__file__).resolve().parent
PROTOS = ("robot_server.proto", "server_manager.proto")


def regenerate(out_dir: Path) -> list[Path]:
    """Run grpc_tools.protoc on PROTOS into ``out_dir``; returns the files written."""
    from grpc_tools import protoc  # build-time dependency only (the `dev`/`test` extras)

    out_dir.mkdir(parents=True, exist_ok=True)
    args = [
        "protoc",
        f"-I{PROTO_DIR}",
        f"--python_out={out_dir}",
        f"--grpc_python_out={out_dir}",
        *(str(PROTO_DIR / p) for p in PROTOS),
    ]
    if protoc.main(args) != 0:
        raise RuntimeError(f"protoc failed: {' '.join(args)}")
    written = []
    for proto in PROTOS:
        stem = proto.removesuffix(".proto")
        grpc_file = out_dir / f"{stem}_pb2_grpc.py"
        text = grpc_file.read_text()
        text = re.sub(rf"^import {stem}_pb2 as", f"from . import {stem}_pb2 as", text, flags=re.M)
        grpc_file.write_text(text)
        written += [out_dir / f"{stem}_pb2.py", grpc_file]
    return written


if __name__ == "__main__":
    target = Path(sys.argv[1]) if len(sys.argv) > 1 else PROTO_DIR
    for path in regenerate(target):
        print(path)
