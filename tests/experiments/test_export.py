"""Export: checkpoint -> TorchScript + sidecar -> load -> the same actions as the policy."""

from __future__ import annotations

import json

import numpy as np
import pytest
import torch

from robogym_ray.cli import main as cli_main
from robogym_ray.errors import ConfigError
from robogym_ray.export import (
    FORMAT,
    export_policy,
    load_checkpoint_policy,
    load_exported,
    load_policy,
    sidecar_path,
)
from robogym_ray.learner.config import D4PGConfig
from robogym_ray.learner.learner import D4PGLearner
from tests.experiments.conftest import POSITIONING, save_learner


def test_exported_policy_acts_like_the_learner_policy(positioning_checkpoint, tmp_path) -> None:
    path, learner = positioning_checkpoint
    out = tmp_path / "export" / "policy.pt"
    info = export_policy(path, out, env_id=POSITIONING)
    assert out.exists() and sidecar_path(out).exists()
    assert (info.obs_dim, info.act_dim, info.policy_hidden) == (15, 6, (32, 16))
    assert info.layer_norm is True
    assert info.action_low == (-1.0,) * 6 and info.format == FORMAT
    module, loaded = load_exported(out)
    assert loaded == info
    obs = torch.as_tensor(np.random.default_rng(0).normal(size=(64, 15)), dtype=torch.float32)
    with torch.no_grad():
        expected = learner.policy(obs)
    torch.testing.assert_close(module(obs), expected, rtol=0, atol=1e-6)
    # One observation at a time, as the robot PC calls it.
    fn = load_policy(out)
    np.testing.assert_allclose(fn(obs[3].numpy()), expected[3].numpy(), atol=1e-6)


@pytest.mark.parametrize("layer_norm", [False, True])
def test_checkpoint_architecture_is_read_from_the_weights(tmp_path, layer_norm: bool) -> None:
    save_learner(tmp_path / "l.pt", 20, 2, layer_norm=layer_norm)
    _, info = load_checkpoint_policy(tmp_path / "l.pt")
    assert (info.obs_dim, info.act_dim, info.policy_hidden) == (20, 2, (32, 16))
    assert info.layer_norm is layer_norm


def test_bad_files_are_config_errors(tmp_path) -> None:
    bad = tmp_path / "bad.pt"
    torch.save({"something": 1}, bad)
    with pytest.raises(ConfigError, match="not a D4PGLearner checkpoint"):
        load_checkpoint_policy(bad)
    with pytest.raises(ConfigError, match="cannot read checkpoint"):
        load_checkpoint_policy(tmp_path / "missing.pt")


def test_env_id_comes_from_the_run_directory(tmp_path, capsys) -> None:
    run = tmp_path / "run"
    (run / "checkpoints").mkdir(parents=True)
    (run / "config.json").write_text(json.dumps({"train": {"task": "positioning"}, "d4pg": {}}))
    save_learner(run / "checkpoints" / "learner.pt", 15, 6)
    checkpoint = run / "checkpoints" / "learner.pt"
    assert cli_main(["export", str(checkpoint), str(tmp_path / "p.pt")]) == 0
    printed = json.loads(capsys.readouterr().out)
    assert printed["env_id"] == POSITIONING
    assert load_policy(run / "checkpoints" / "learner.pt").info.env_id == POSITIONING


def test_a_run_folder_gives_its_checkpoint(tmp_path, capfd) -> None:
    """The summary's ``files:`` line names the run's folder: export and evaluate take it (its
    checkpoint, the file the summary's ``checkpoint`` names) and say which file they took; a
    folder with no checkpoint is one error line."""
    run = tmp_path / "run"
    (run / "checkpoints").mkdir(parents=True)
    (run / "config.json").write_text(json.dumps({"train": {"task": "positioning"}, "d4pg": {}}))
    checkpoint = run / "checkpoints" / "learner.pt"
    save_learner(checkpoint, 15, 6)
    took = f"{run} is a run folder: using its checkpoint {checkpoint}\n"
    assert cli_main(["export", str(run), str(tmp_path / "p.pt")]) == 0
    out, err = capfd.readouterr()
    assert err == took and json.loads(out)["source"].startswith(str(checkpoint))
    assert cli_main(["evaluate", str(run), "--episodes", "1", "--max-steps", "2"]) == 0
    out, err = capfd.readouterr()
    assert err.startswith(took) and POSITIONING in out  # (then maybe pybullet's banner)
    assert cli_main(["export", str(run / "checkpoints"), str(tmp_path / "q.pt")]) == 0
    assert capfd.readouterr().err == took.replace(str(run), str(run / "checkpoints"), 1)
    empty = tmp_path / "empty"
    empty.mkdir()
    for argv in (["export", str(empty), str(tmp_path / "e.pt")], ["evaluate", str(empty)]):
        assert cli_main(argv) == 2
        assert capfd.readouterr().err == (
            f"error: {empty} is a folder with no checkpoint (checkpoints/learner.pt or "
            "learner.pt): give a run folder, a learner.pt or an exported policy\n"
        )
    assert not (tmp_path / "e.pt").exists()


def test_a_run_with_a_policy_average_ships_the_average(tmp_path, capsys) -> None:
    run = tmp_path / "run"
    (run / "checkpoints").mkdir(parents=True)
    (run / "config.json").write_text(json.dumps({"train": {"task": "positioning"}, "d4pg": {}}))
    checkpoint = run / "checkpoints" / "learner.pt"
    cfg = D4PGConfig(
        policy_hidden=(32, 16),
        critic_hidden=(32,),
        replay_capacity=256,
        batch_size=8,
        policy_average_tau=0.01,
    )
    learner = D4PGLearner(cfg, 15, 6, seed=0)
    with torch.no_grad():  # the online policy moves away from its average
        learner.policy.net[0].weight.add_(0.5)
    learner.save(checkpoint)
    obs = torch.as_tensor(np.random.default_rng(1).normal(size=(8, 15)), dtype=torch.float32)
    with torch.no_grad():
        averaged, online = learner.policy_average(obs), learner.policy(obs)
    assert not torch.allclose(averaged, online)

    module, info = load_checkpoint_policy(checkpoint)
    torch.testing.assert_close(module(obs), averaged, rtol=0, atol=0)
    assert info.source == f"{checkpoint}#policy_average"
    module, info = load_checkpoint_policy(checkpoint, online=True)
    torch.testing.assert_close(module(obs), online, rtol=0, atol=0)
    assert info.source == str(checkpoint)

    for flags, expected in (([], averaged), (["--online-weights"], online)):
        out = tmp_path / f"p{len(flags)}.pt"
        assert cli_main(["export", str(checkpoint), str(out), *flags]) == 0
        capsys.readouterr()
        module, _ = load_exported(out)
        torch.testing.assert_close(module(obs), expected, rtol=0, atol=1e-6)
    with pytest.raises(ConfigError, match="exported policy"):
        load_policy(tmp_path / "p0.pt", online=True)


def probe_export_on_a_full_disk(checkpoint: str, disk: str) -> None:
    """Runs on a full tmpfs (``tests/full_disk.py``): export a policy and an ONNX onto it."""
    from pathlib import Path

    from robogym_ray.errors import DiskWriteError
    from tests.full_disk import fill, report, tmp_files

    disk_dir = Path(disk)
    fill(disk_dir)
    errors = {}
    for name in ("policy.pt", "policy.onnx"):
        try:
            export_policy(checkpoint, disk_dir / name, env_id=POSITIONING)
            errors[name] = None
        except DiskWriteError as exc:
            errors[name] = {"type": type(exc).__name__, "path": exc.path, "what": exc.what}
        except ImportError:  # the onnx extra is not installed here
            errors[name] = "no onnx"
    files = sorted(p.name for p in disk_dir.iterdir())
    report({"errors": errors, "files": files, "tmp": tmp_files(disk_dir)})


def test_export_on_a_full_disk_leaves_no_partial_file(positioning_checkpoint, tmp_path) -> None:
    from tests.full_disk import run_on_tmpfs

    path, _ = positioning_checkpoint
    disk = tmp_path / "disk"
    out = run_on_tmpfs(disk, "1m", f"{__name__}:probe_export_on_a_full_disk", str(path), str(disk))
    assert out["errors"]["policy.pt"] == {"type": "DiskFullError", "what": "exported policy",
                                          "path": str(disk / "policy.pt")}  # fmt: skip
    if out["errors"]["policy.onnx"] != "no onnx":
        assert out["errors"]["policy.onnx"]["path"] == str(disk / "policy.onnx")
    assert out["files"] == ["filler"] and out["tmp"] == []


def test_a_sidecar_that_cannot_be_written_keeps_the_export_from_appearing(
    positioning_checkpoint, tmp_path, capfd
) -> None:
    """Without its sidecar an exported file would read as a learner checkpoint: OUT is renamed
    into place only after its sidecar is written, and a failed re-export leaves the old OUT."""
    path, _ = positioning_checkpoint
    out = tmp_path / "export" / "policy.pt"
    export_policy(path, out, env_id=POSITIONING)
    before = out.read_bytes()
    sidecar_path(out).unlink()
    sidecar_path(out).mkdir()  # where the sidecar goes, a directory: its rename fails
    fresh = tmp_path / "fresh" / "policy.pt"
    sidecar_path(fresh).mkdir(parents=True)
    for target in (out, fresh):
        assert cli_main(["export", str(path), str(target), "--env-id", POSITIONING]) != 0
        err = capfd.readouterr().err.strip().splitlines()
        assert len(err) == 1 and "cannot write exported policy's sidecar" in err[0], err
    assert out.read_bytes() == before and not fresh.exists()
    assert sorted(p.name for p in tmp_path.rglob("*") if p.is_file()) == ["learner.pt", "policy.pt"]
