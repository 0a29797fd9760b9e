"""A run whose storage is an object store: an S3-compatible server started on 127.0.0.1 (moto's
standalone server mode, which pyarrow's and fsspec's own tests use), the real CLI with its own
embedded Ray. Every file of the run lands in the bucket; ``evaluate``, ``export`` and
``--init-from`` read it from there."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from robogym_ray import children

BUCKET = "robogym"


@pytest.fixture(scope="session")
def s3_server() -> Iterator[str]:
    """An S3 server on 127.0.0.1 with the test bucket, started once for the session (the tests
    keep to key prefixes of their own); its endpoint URL."""
    pytest.importorskip("boto3")
    moto_server = pytest.importorskip("moto.server")
    server = moto_server.ThreadedMotoServer(ip_address="127.0.0.1", port=0, verbose=False)
    server.start()
    host, port = server.get_host_and_port()
    try:
        yield f"http://{host}:{port}"
    finally:
        server.stop()


@pytest.fixture
def s3(s3_server: str, monkeypatch: pytest.MonkeyPatch) -> Any:
    """A client of the bucket; the AWS_* variables that reach it, set for this test."""
    import boto3

    for key, value in {
        "AWS_ACCESS_KEY_ID": "testing",
        "AWS_SECRET_ACCESS_KEY": "testing",
        "AWS_DEFAULT_REGION": "us-east-1",
        "AWS_ENDPOINT_URL": s3_server,
    }.items():
        monkeypatch.setenv(key, value)
    client = boto3.client("s3", endpoint_url=s3_server)
    if BUCKET not in {b["Name"] for b in client.list_buckets()["Buckets"]}:
        client.create_bucket(Bucket=BUCKET)
    return client


def cli(*args: str, timeout: float = 400) -> subprocess.CompletedProcess:
    env = {**os.environ, "RAY_AUTH_MODE": "disabled"}
    return children.run(
        [sys.executable, "-m", "robogym_ray.cli", *args],
        env=env, capture_output=True, text=True, timeout=timeout,
    )  # fmt: skip


def keys(client: Any, prefix: str) -> list[str]:
    listing = client.list_objects_v2(Bucket=BUCKET, Prefix=prefix)
    return sorted(o["Key"][len(prefix) :] for o in listing.get("Contents", []))


@pytest.mark.slow
def test_a_run_on_s3_storage_and_reading_it_back(s3: Any, tmp_path: Path) -> None:
    storage = f"s3://{BUCKET}/runs"
    common = ["--task", "navigation", "--workers", "1", "--envs-per-worker", "2",
              "--storage", storage, "--no-progress", "--num-cpus", "2"]  # fmt: skip
    out = cli("train", *common, "--run-name", "first", "--total-steps", "1500", "--save-replay",
              "--policy-snapshot-every-s", "1", "--select-episodes", "2")  # fmt: skip
    assert out.returncode == 0, out.stdout[-2000:] + out.stderr[-3000:]
    files = keys(s3, "runs/first/")
    expected = {"config.json", "summary.json", "checkpoints/learner.pt",
                "checkpoints/learner.pt.replay.npz", "checkpoints/policy-best.pt"}  # fmt: skip
    assert expected <= set(files), files
    assert any(f.startswith("events.out.tfevents.") for f in files), files
    assert any(f.startswith("checkpoints/policy-") and f.endswith("min.pt") for f in files)
    assert not (Path.cwd() / "runs" / "first").exists()  # nothing written beside the driver
    body = s3.get_object(Bucket=BUCKET, Key="runs/first/summary.json")["Body"].read()
    summary = json.loads(body)
    learner_pt = f"{storage}/first/checkpoints/learner.pt"
    assert summary["checkpoint"] == learner_pt
    assert summary["logdir"] == f"{storage}/first"  # the run's folder, named once
    assert summary["storage"] == {"node": "(object store)"}
    assert f"files:       {storage}/first/" in out.stdout

    # The run's files are read from the bucket: evaluate, export, --init-from. The first two
    # start no Ray, so they run in this process (the AWS_* variables set above reach them).
    from robogym_ray.cli import main

    argv = ["evaluate", learner_pt, "--episodes", "2", "--max-steps", "30",
            "--out", str(tmp_path / "eval")]  # fmt: skip
    assert main(argv) == 0
    result = json.loads((tmp_path / "eval" / "evaluation.json").read_text())
    assert result["env_id"] == "RoboGymRay/ObstacleAvoidanceMir100Sim-v0"  # from config.json
    assert len(result["episodes"]) == 2
    assert main(["export", learner_pt, str(tmp_path / "nav.pt")]) == 0
    assert (tmp_path / "nav.pt").stat().st_size > 0
    out = cli("train", *common, "--run-name", "second", "--total-steps", "300",
              "--init-from", learner_pt, "--no-evaluator", "--json")  # fmt: skip
    assert out.returncode == 0, out.stderr[-3000:]
    second = json.loads(out.stdout.strip().splitlines()[-1])
    assert second["learner_restored_from_step"] == summary["learner_steps"]
    assert second["learner_restored_replay"] > 0
    assert "checkpoints/learner.pt" in keys(s3, "runs/second/")


def test_storage_files_on_s3_and_on_a_path(s3: Any, tmp_path: Path) -> None:
    """The same RunStorage calls on an object store and a local path; single files fetched with
    what sits beside them, from the top of a bucket too."""
    from robogym_ray.errors import ConfigError
    from robogym_ray.storage import RunStorage, is_uri, local_file, read_text

    for root in (f"s3://{BUCKET}/unit/run", str(tmp_path / "unit" / "run")):
        store = RunStorage(root)
        assert store.is_local == (not is_uri(root))
        assert not store.holds_run() and store.names("checkpoints") == []
        store.write_bytes("config.json", b'{"train": {}}', "config")
        store.write_bytes("checkpoints/learner.pt", b"nets", "checkpoint")
        store.write_bytes("checkpoints/learner.pt.replay.npz", b"replay", "replay")
        assert store.holds_run() and store.exists("checkpoints/learner.pt")
        assert store.names("checkpoints") == ["learner.pt", "learner.pt.replay.npz"]
        assert read_text(store.location("config.json")) == '{"train": {}}'
        store.delete("checkpoints/learner.pt.replay.npz")
        assert store.names("checkpoints") == ["learner.pt"]
    local = Path(local_file(f"s3://{BUCKET}/unit/run/checkpoints/learner.pt"))
    assert local.read_bytes() == b"nets"
    assert (local.parent.parent / "config.json").read_text() == '{"train": {}}'
    s3.put_object(Bucket=BUCKET, Key="nav.pt", Body=b"policy")
    s3.put_object(Bucket=BUCKET, Key="nav.json", Body=b"{}")
    top = Path(local_file(f"s3://{BUCKET}/nav.pt"))
    assert top.read_bytes() == b"policy" and (top.parent / "nav.json").read_text() == "{}"
    with pytest.raises(ConfigError, match="no such object"):
        local_file(f"s3://{BUCKET}/missing.pt", "policy")
    assert local_file(str(tmp_path / "x.pt")) == str(tmp_path / "x.pt")  # a path as it is
    # A run folder in a bucket gives its checkpoint (evaluate, export); a file is read as it is.
    from robogym_ray.export import run_checkpoint
    from robogym_ray.storage import check_writable

    run = f"s3://{BUCKET}/unit/run"
    assert run_checkpoint(run) == f"{run}/checkpoints/learner.pt"
    assert run_checkpoint(f"{run}/checkpoints/learner.pt") is None
    # The storage check before Ray writes a file at the root and removes it again.
    check_writable(RunStorage(f"s3://{BUCKET}/unit"), "--storage")
    assert not [key for key in keys(s3, "unit/") if "storage-check" in key]


def test_a_relative_storage_in_a_ray_job_lands_on_the_head(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from robogym_ray.storage import resolve_root

    job_copy = "/tmp/ray/session_x/runtime_resources/working_dir_files/_ray_pkg_abc"
    monkeypatch.setenv("ROBOGYM_RAY_RESULTS", str(tmp_path / "results"))
    assert resolve_root("runs", cwd=job_copy) == str(tmp_path / "results" / "runs")
    assert resolve_root("runs", cwd="/home/me/project") == "/home/me/project/runs"
    assert resolve_root("/data/runs", cwd=job_copy) == "/data/runs"
    assert resolve_root("s3://b/runs", cwd=job_copy) == "s3://b/runs"
    monkeypatch.delenv("ROBOGYM_RAY_RESULTS")
    assert resolve_root("runs", cwd=job_copy) == str(Path.home() / "robogym_ray_results" / "runs")
