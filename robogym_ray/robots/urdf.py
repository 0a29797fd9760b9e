"""URDF files for robots whose geometry is written in code rather than shipped.

A robot model that generates its URDF from its published parameters (the UR arms, the Panda)
hands the text here and gets a path PyBullet can load. No PyBullet import: robot cards import
the models that call this.
"""

from __future__ import annotations

import hashlib
import os
import tempfile


def cached_urdf(stem: str, text: str) -> str:
    """Write ``text`` to a per-user cache file ``<stem>_<content hash>.urdf`` and return its path.

    The hash in the name makes concurrent writers (several robot servers) agree on identical
    content, and a changed geometry gets a new file instead of reading a stale one; the file is
    written then renamed, so a concurrent reader never sees half of it.
    """
    digest = hashlib.sha256(text.encode()).hexdigest()[:12]
    directory = os.path.join(tempfile.gettempdir(), f"robogym_ray_urdf_{os.getuid()}")
    os.makedirs(directory, exist_ok=True)
    path = os.path.join(directory, f"{stem}_{digest}.urdf")
    if not os.path.exists(path):
        fd, tmp = tempfile.mkstemp(dir=directory, suffix=".urdf.tmp")
        with os.fdopen(fd, "w") as f:
            f.write(text)
        os.replace(tmp, path)
    return path
