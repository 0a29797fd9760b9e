"""The save path on a full disk (a real tmpfs, ``tests/full_disk.py``): a checkpoint, replay,
policy file or ``--init-from`` copy that cannot be written raises ``DiskFullError`` naming the
file a user knows, leaves no temporary file, and leaves the last good checkpoint as it was,
loadable."""

from __future__ import annotations

import hashlib
import pickle
from pathlib import Path
from typing import Any

from robogym_ray.errors import DiskFullError, DiskWriteError
from tests.full_disk import fill, report, run_on_tmpfs, tmp_files


def _digest(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _error(call: Any) -> dict[str, Any]:
    try:
        call()
    except DiskWriteError as exc:
        return {"type": type(exc).__name__, "path": exc.path, "what": exc.what, "msg": str(exc)}
    return {"type": None}


def probe(disk: str) -> None:
    """Runs on the tmpfs: one good checkpoint, then writes that cannot fit."""
    from robogym_ray.learner import checkpoint
    from robogym_ray.learner.service import LearnerService
    from tests.learner.test_service_replay import ACT, OBS, SMALL, batch

    disk_dir = Path(disk)
    ckpt = disk_dir / "checkpoints"
    service = LearnerService(SMALL, OBS, ACT, checkpoint_dir=str(ckpt), checkpoint_every=0)
    # A replay of some 200 kB, a checkpoint of a few kB (inserted only: no learner steps).
    service.learner.add(batch(4000, seed=0), None)
    good = ckpt / checkpoint.CHECKPOINT_NAME
    service.checkpoint()
    before = {"digest": _digest(good), "steps": service.version}
    out: dict[str, Any] = {"before": before}

    fill(disk_dir)
    out["checkpoint"] = _error(service.checkpoint)
    out["checkpoint_tmp"] = tmp_files(disk_dir)
    state = checkpoint.learner_state(service.learner)
    out["policy"] = _error(lambda: checkpoint.write_atomic(disk_dir / "policy-best.pt", state))
    out["replay"] = _error(
        lambda: checkpoint.write_replay(disk_dir / "r.npz", service.learner.replay.state_dict())
    )
    # Room for the networks, not for the replay beside them.
    filler = disk_dir / "filler"
    with open(filler, "r+b") as f:
        f.truncate(filler.stat().st_size - good.stat().st_size - 65536)
    out["with_replay"] = _error(lambda: service.checkpoint(include_replay=True))

    # --init-from copied into a new run's directory on a full disk: no partial learner.pt,
    # which a re-run would take for the run's own checkpoint.
    from robogym_ray.storage import RunStorage
    from robogym_ray.training.program import seed_checkpoint

    fill(disk_dir)
    seeded = disk_dir / "run" / "checkpoints"
    storage = RunStorage(str(disk_dir / "run"))
    out["seed"] = _error(lambda: seed_checkpoint(str(good), storage, SMALL, OBS, ACT))
    out["seeded_files"] = sorted(p.name for p in seeded.iterdir()) if seeded.exists() else []

    out["tmp"] = tmp_files(disk_dir)
    out["files"] = sorted(p.name for p in ckpt.iterdir())
    out["after"] = {"digest": _digest(good), "steps": int(checkpoint.read(good)["num_steps"])}
    report(out)


def test_saving_on_a_full_disk_raises_the_typed_error_and_leaves_the_last_checkpoint(
    tmp_path: Path,
) -> None:
    disk = tmp_path / "disk"
    out = run_on_tmpfs(disk, "2m", f"{__name__}:probe", str(disk))
    good = disk / "checkpoints" / "learner.pt"

    assert out["checkpoint"]["type"] == "DiskFullError"
    assert out["checkpoint"]["path"] == str(good)  # the real name, not the temporary one
    assert out["checkpoint"]["msg"] == f"cannot write learner checkpoint {good}: " + (
        "no space left on device"
    )
    assert out["checkpoint_tmp"] == []
    assert out["policy"]["type"] == "DiskFullError"
    assert out["policy"]["path"] == str(disk / "policy-best.pt")
    assert out["replay"]["type"] == "DiskFullError"
    assert out["replay"]["path"] == str(disk / "r.npz")

    # The networks fitted, the replay did not: neither is renamed into place.
    assert out["with_replay"]["type"] == "DiskFullError"
    assert out["with_replay"]["what"] == "learner replay"
    assert out["with_replay"]["path"] == f"{good}.replay.npz"

    assert out["seed"]["type"] == "DiskFullError"
    assert out["seed"]["path"] == str(disk / "run" / "checkpoints" / "learner.pt")
    assert out["seed"]["what"] == "learner checkpoint"
    assert out["seeded_files"] == []

    assert out["tmp"] == []
    assert out["files"] == ["learner.pt"]
    assert out["after"] == out["before"]  # untouched, and loadable


def test_the_typed_error_survives_pickling_as_ray_sends_it() -> None:
    import errno

    exc = DiskWriteError.of("learner checkpoint", "/r/learner.pt", OSError(errno.ENOSPC, "x"))
    back = pickle.loads(pickle.dumps(exc))
    assert type(back) is DiskFullError
    assert (back.path, back.reason, back.what) == ("/r/learner.pt", "no space left on device",
                                                   "learner checkpoint")  # fmt: skip
    assert str(back) == "cannot write learner checkpoint /r/learner.pt: no space left on device"
    other = DiskWriteError.of("summary", "/r/summary.json", OSError(errno.EACCES, "x"))
    assert type(other) is DiskWriteError and other.reason == "permission denied"
