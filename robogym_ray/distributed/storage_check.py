"""Before a multi-node run starts: can every node read and write the run's storage?

A path that exists on the driver's machine may be a different, node-local folder on every other
node (their own disks): a learner there would checkpoint where no other node - and no user -
finds it, and one restarted elsewhere would find nothing. Ray Train refuses such storage in a
multi-node run; so does this. The driver writes a marker with a random token; a task pinned to
each alive node reads it back and writes (then removes) a file of its own.
"""

from __future__ import annotations

import secrets
from typing import Any

import ray
from ray.util.scheduling_strategies import NodeAffinitySchedulingStrategy

from robogym_ray.errors import ConfigError
from robogym_ray.storage import STORAGE_MARKER, RunStorage, write_marker


def _probe(storage: RunStorage, marker: str, token: str, node_id: str) -> str:
    """On one node: '' when it reads the driver's token and can write beside it, else why."""
    try:
        seen = storage.read_bytes(marker).decode(errors="replace")
    except (OSError, ConfigError) as exc:
        return f"cannot read it ({_reason(exc)})"
    if seen != token:
        return "sees another file there (a folder of its own, not the driver's)"
    try:
        storage.write_bytes(f"{marker}.{node_id}", token.encode(), "storage check")
        storage.delete(f"{marker}.{node_id}")
    except Exception as exc:  # noqa: BLE001 - any failure to write is the answer
        return f"cannot write there ({_reason(exc)})"
    return ""


def _reason(exc: BaseException) -> str:
    """Why, in a few words: an OSError's strerror ("No such file or directory") or the start of
    the message."""
    strerror = getattr(exc, "strerror", None)
    return str(strerror) if strerror else (str(exc).splitlines() or [type(exc).__name__])[0][:120]


_probe_task = ray.remote(num_cpus=0, max_retries=0)(_probe)


def check_reachable(storage: RunStorage, timeout_s: float = 120.0) -> None:
    """ConfigError naming every alive node that cannot read and write ``storage`` (nothing to
    check with one node). The marker is removed again either way."""
    nodes = [n for n in ray.nodes() if n.get("Alive")]
    if len(nodes) <= 1:
        return
    marker = f"{STORAGE_MARKER}-{secrets.token_hex(4)}"
    token = secrets.token_hex(16)
    write_marker(storage, marker, token.encode(), "storage")  # one line if the driver cannot
    try:
        refs: dict[Any, dict[str, Any]] = {}
        for node in nodes:
            strategy = NodeAffinitySchedulingStrategy(node["NodeID"], soft=False)
            ref = _probe_task.options(scheduling_strategy=strategy).remote(
                storage, marker, token, node["NodeID"]
            )
            refs[ref] = node
        failed = []
        for ref, node in refs.items():
            try:
                why = ray.get(ref, timeout=timeout_s)
            except Exception as exc:  # noqa: BLE001 - a node that cannot even run the check
                why = f"did not answer ({type(exc).__name__})"
            if why:
                failed.append(f"{node.get('NodeManagerAddress', '?')} "
                              f"[{node['NodeID'][:8]}] {why}")  # fmt: skip
    finally:
        storage.delete(marker)
    if failed:
        raise ConfigError(
            f"storage {storage.location()} is not shared by the cluster's {len(nodes)} nodes: "
            f"{'; '.join(failed)}. Pass --storage a path every node mounts (e.g. NFS) or an "
            "object store (s3://bucket/prefix, gs://...)"
        )
