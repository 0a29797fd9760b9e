"""Bad input to any command: one ``error:`` line naming the file or key, exit code 2, and nothing
started or written first (no Ray, no run directory).

Issue "Hardening, second round", part 3: random bytes or a cut TorchScript file gave tracebacks,
an empty ``--init-from`` "cannot read checkpoint ...: " with no reason (after Ray had started
and the run directory was made), and config values of the wrong type crashed once Ray was up.
The commands run in this process (``cli.main``); ``capfd`` sees stderr at the file-descriptor
level, so a library's own print (torch's warnings) would count as a second line too.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import pytest
import torch

import robogym_ray
from robogym_ray import children
from robogym_ray.cli import main
from robogym_ray.errors import ConfigError
from robogym_ray.learner.checkpoint import replay_path
from robogym_ray.learner.config import D4PGConfig
from robogym_ray.learner.learner import D4PGLearner
from robogym_ray.learner.networks import Policy
from robogym_ray.training import setup as run_setup

PENDULUM = dict(policy_hidden=(256, 256), critic_hidden=(256, 256))  # the pendulum preset's


# Every command here must refuse its input before it starts Ray (tests/conftest.py's tripwire).
pytestmark = pytest.mark.usefixtures("ray_must_not_start")


def fails(capfd: pytest.CaptureFixture, *argv: str) -> str:
    """Run ``robogym-ray ARGV``; the one stderr line it must print (exit code 2, and Ray not
    started: ``ray_must_not_start``)."""
    capfd.readouterr()
    assert main(list(argv)) == 2
    err = capfd.readouterr().err
    lines = err.splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), err[:2000]
    return lines[0]


def train_fails(capfd: pytest.CaptureFixture, logdir: Path, *argv: str) -> str:
    existed = logdir.exists()
    line = fails(capfd, "train", "--logdir", str(logdir), "--total-steps", "10", *argv)
    assert not logdir.exists() or not any(logdir.iterdir())  # no run directory
    assert existed or not logdir.exists()  # nor the run root the storage check wrote in
    return line


def learner_file(path: Path, obs_dim: int, act_dim: int, **d4pg: object) -> Path:
    """A real (untrained) learner's checkpoint, as training writes it."""
    cfg = D4PGConfig(replay_capacity=256, batch_size=8, **d4pg)  # type: ignore[arg-type]
    D4PGLearner(cfg, obs_dim, act_dim, seed=0).save(path)
    return path


def exported_policy(tmp_path: Path) -> Path:
    """A real exported navigation policy (TorchScript and its sidecar)."""
    out = tmp_path / "policy.ts"
    policy = Policy(20, 2, (16,), False).eval()
    torch.jit.trace(policy, torch.zeros(1, 20)).save(str(out))
    sidecar = {"obs_dim": 20, "act_dim": 2, "policy_hidden": [16], "layer_norm": False,
               "env_id": "RoboGymRay/ObstacleAvoidanceMir100Sim-v0",
               "format": "robogym-ray-policy/torchscript-v1"}  # fmt: skip
    Path(f"{out}.json").write_text(json.dumps(sidecar))
    return out


# -- checkpoint and policy files ---------------------------------------------------------------
def test_evaluate_random_bytes(tmp_path: Path, capfd: pytest.CaptureFixture) -> None:
    bad = tmp_path / "random.pt"
    bad.write_bytes(bytes(range(256)) * 16)  # was: an UnpicklingError traceback
    line = fails(capfd, "evaluate", str(bad), "--episodes", "1")
    assert str(bad) in line and "wrong format" in line


def test_evaluate_empty_and_truncated_checkpoints(
    tmp_path: Path, capfd: pytest.CaptureFixture
) -> None:
    empty = tmp_path / "empty.pt"
    empty.touch()
    assert "empty file" in fails(capfd, "evaluate", str(empty))
    good = learner_file(tmp_path / "learner.pt", 20, 2, policy_hidden=(16,), critic_hidden=(16,))
    cut = tmp_path / "cut.pt"
    cut.write_bytes(good.read_bytes()[: good.stat().st_size // 2])
    assert "truncated or corrupt" in fails(capfd, "evaluate", str(cut))


def test_evaluate_corrupt_exported_policy(tmp_path: Path, capfd: pytest.CaptureFixture) -> None:
    out = exported_policy(tmp_path)
    out.write_bytes(out.read_bytes()[:300])  # was: a RuntimeError traceback
    line = fails(capfd, "evaluate", str(out), "--episodes", "1")
    assert line.startswith(f"error: cannot load exported policy {out}: ")
    line = fails(capfd, "run-policy", "--policy", str(out), "--rs-address", "127.0.0.1:1")
    assert "cannot load exported policy" in line


def test_exported_policy_sidecar_is_checked(tmp_path: Path, capfd: pytest.CaptureFixture) -> None:
    out = exported_policy(tmp_path)
    sidecar = Path(f"{out}.json")
    data = json.loads(sidecar.read_text())
    sidecar.write_text(json.dumps({**data, "obs_dim": "20"}))
    assert f"{sidecar}.obs_dim = '20'; expected an integer" in fails(capfd, "evaluate", str(out))
    sidecar.write_text(json.dumps({**data, "act_dim": 3}))  # the module answers 2 actions
    assert "sidecar says (1, 3)" in fails(capfd, "evaluate", str(out))
    sidecar.write_text("[" * 100_000)
    assert "nested too deeply" in fails(capfd, "evaluate", str(out))


def test_export_of_a_bad_checkpoint_writes_nothing(
    tmp_path: Path, capfd: pytest.CaptureFixture
) -> None:
    bad, out = tmp_path / "bad.pt", tmp_path / "out" / "policy.ts"
    bad.write_bytes(b"\x00" * 100)
    assert "wrong format" in fails(capfd, "export", str(bad), str(out))
    assert not (tmp_path / "out").exists()
    good = learner_file(tmp_path / "learner.pt", 20, 2, policy_hidden=(16,), critic_hidden=(16,))
    (tmp_path / "dir").mkdir()
    assert "is a directory" in fails(capfd, "export", str(good), str(tmp_path / "dir"))


@pytest.mark.parametrize(
    ("content", "reason"),
    [
        (b"", "empty file (0 bytes)"),  # was: "cannot read checkpoint ...: " and nothing more
        (bytes(range(256)), "not a torch checkpoint of tensors (wrong format)"),
        (b"PK\x03\x04" + b"\x00" * 64, "truncated or corrupt"),
    ],
)
def test_train_init_from_unreadable_file(
    tmp_path: Path, capfd: pytest.CaptureFixture, content: bytes, reason: str
) -> None:
    source = tmp_path / "learner.pt"
    source.write_bytes(content)
    line = train_fails(capfd, tmp_path / "runs", "--init-from", str(source))
    assert line == f"error: cannot read checkpoint {source}: {reason}" or reason in line


def test_train_init_from_incomplete_or_mismatched_checkpoint(
    tmp_path: Path, capfd: pytest.CaptureFixture
) -> None:
    runs = tmp_path / "runs"
    policy_only = tmp_path / "policy.pt"
    torch.save({"nets": {"policy": {}}}, policy_only)
    line = train_fails(capfd, runs, "--task", "pendulum", "--init-from", str(policy_only))
    assert f"{policy_only} is not a complete learner checkpoint: no nets.critic" in line
    small = learner_file(tmp_path / "small.pt", 3, 1, policy_hidden=(16,), critic_hidden=(16,))
    line = train_fails(capfd, runs, "--task", "pendulum", "--init-from", str(small))
    assert "not a D4PG checkpoint for obs_dim=3" in line and "size mismatch" in line


def test_train_init_from_with_a_broken_replay(tmp_path: Path, capfd: pytest.CaptureFixture) -> None:
    source = learner_file(tmp_path / "learner.pt", 3, 1, **PENDULUM)  # type: ignore[arg-type]
    replay_path(source).write_bytes(b"not an archive")
    line = train_fails(capfd, tmp_path / "runs", "--task", "pendulum", "--init-from", str(source))
    assert f"cannot read replay {replay_path(source)}" in line


def test_a_taken_run_name_is_refused_and_resume_checks_its_checkpoint(
    tmp_path: Path, capfd: pytest.CaptureFixture
) -> None:
    """A --run-name that holds a run is refused unless --resume; a resumed run with other
    network sizes than its checkpoint's is refused too (the learner would crash restoring it,
    after Ray had started). Both in one line, before anything starts or is written."""
    runs = tmp_path / "runs"
    own = runs / "r" / "checkpoints" / "learner.pt"
    own.parent.mkdir(parents=True)
    learner_file(own, 3, 1, policy_hidden=(16,), critic_hidden=(16,))
    capfd.readouterr()
    argv = ["train", "--logdir", str(runs), "--run-name", "r", "--total-steps", "10"]
    assert main([*argv, "--task", "pendulum"]) == 2
    line = capfd.readouterr().err.strip()
    assert line == (
        f"error: run folder {runs / 'r'} holds a run already: pass --resume to continue it, "
        "or another --run-name (leave it out for a new name each run)"
    )
    assert main([*argv, "--task", "pendulum", "--resume"]) == 2
    line = capfd.readouterr().err.strip()
    assert line.startswith(f"error: --resume: the run's checkpoint {own}")
    assert "not a D4PG checkpoint for obs_dim=3" in line and "\n" not in line
    assert sorted(p.name for p in runs.rglob("*")) == ["checkpoints", "learner.pt", "r"]
    assert main([*argv[:-4], "--run-name", "none", "--task", "pendulum", "--resume"]) == 2
    line = capfd.readouterr().err.strip()
    assert line == f"error: --resume: {runs / 'none'} has no checkpoint to continue from"


def test_a_good_init_from_passes_the_check(tmp_path: Path) -> None:
    source = learner_file(tmp_path / "learner.pt", 3, 1, **PENDULUM)  # type: ignore[arg-type]
    d4pg = D4PGConfig(**PENDULUM)  # type: ignore[arg-type]
    state = run_setup.check_init_from(str(source), d4pg, 3, 1)
    assert state["num_steps"] == 0


# -- config files ------------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("section", "values", "expected"),
    [
        ("d4pg", {"policy_hidden": 256}, "d4pg.policy_hidden = 256; expected a list of integers"),
        ("train", {"seed": "abc"}, "train.seed = 'abc'; expected an integer"),
        ("train", {"workers": 1.5}, "train.workers = 1.5; expected an integer"),
        ("train", {"workers": True}, "train.workers = True; expected an integer"),
        ("train", {"logdir": 5}, "train.logdir = 5; expected a string"),
        (
            "train",
            {"real_robot": "127.0.0.1:50051"},  # was: "--real-robot '1' is not HOST:PORT"
            "train.real_robot = '127.0.0.1:50051'; expected a list of strings",
        ),
        ("emulation", {"latency_ticks": "2"}, "emulation.latency_ticks = '2'; expected an"),
        # null is a step total no longer: with max_wall_s it means no step cap (test_help.py)
        ("train", {"max_wall_s": None, "total_steps": "3000"}, "train.total_steps = '3000'"),
    ],
)
def test_config_values_of_the_wrong_type(
    tmp_path: Path, capfd: pytest.CaptureFixture, section: str, values: dict, expected: str
) -> None:
    config = tmp_path / "config.json"
    config.write_text(json.dumps({section: values}))
    line = train_fails(capfd, tmp_path / "runs", "--config", str(config))
    assert line == f"error: {config}: {expected}" or f"{config}: {expected}" in line


def test_a_wrong_type_in_a_base_file_names_that_file(
    tmp_path: Path, capfd: pytest.CaptureFixture
) -> None:
    (tmp_path / "base.json").write_text(json.dumps({"train": {"seed": [1]}}))
    leaf = tmp_path / "leaf.json"
    leaf.write_text(json.dumps({"extends": "base.json"}))
    line = train_fails(capfd, tmp_path / "runs", "--config", str(leaf))
    assert "base.json: train.seed = [1]; expected an integer" in line


def test_deeply_nested_config(tmp_path: Path, capfd: pytest.CaptureFixture) -> None:
    config = tmp_path / "deep.json"
    config.write_text('{"train": {"task": ' + "[" * 100_000 + "]" * 100_000 + "}}")
    line = train_fails(capfd, tmp_path / "runs", "--config", str(config))
    assert line == f"error: cannot read config file {config}: JSON nested too deeply"


def test_long_keys_and_values_are_quoted_in_part(
    tmp_path: Path, capfd: pytest.CaptureFixture
) -> None:
    config, runs = tmp_path / "long.json", tmp_path / "runs"
    config.write_text(json.dumps({"train": {"k" * 1_000_000: 1}}))
    line = train_fails(capfd, runs, "--config", str(config))
    assert "unknown field(s) ['kkkk" in line and "chars cut" in line and len(line) < 2000
    for key in ("task", "sim_path"):
        config.write_text(json.dumps({"train": {key: "v" * 1_000_000}}))
        line = train_fails(capfd, runs, "--config", str(config))
        assert "'vvvv" in line and "chars cut" in line and len(line) < 2000


# -- addresses ---------------------------------------------------------------------------------
def test_addresses_are_checked_before_anything_starts(
    tmp_path: Path, capfd: pytest.CaptureFixture
) -> None:
    assert "--address 'nohost'" in train_fails(capfd, tmp_path / "runs", "--address", "nohost")
    out = exported_policy(tmp_path)
    line = fails(capfd, "run-policy", "--policy", str(out), "--rs-address", "robot:port")
    assert line == "error: --rs-address 'robot:port' is not HOST:PORT (port 1-65535)"
    line = fails(capfd, "evaluate", str(out), "--rs-address", "robot:70000")
    assert "--rs-address 'robot:70000'" in line
    line = fails(capfd, "resume-robot", "arm", "--ray-address", "nowhere")
    assert line == (
        "error: --ray-address 'nowhere' is not auto, HOST:PORT or ray://HOST:PORT (port 1-65535)"
    )
    line = fails(capfd, "manager", "--port", "0", "--ray-address", "nowhere")
    assert line == (
        "error: --ray-address 'nowhere' is not auto, HOST:PORT or ray://HOST:PORT (port 1-65535)"
    )


def test_train_checks_cpus_and_logdir_before_ray(
    tmp_path: Path, capfd: pytest.CaptureFixture
) -> None:
    runs = tmp_path / "runs"
    line = train_fails(capfd, runs, "--workers", "64", "--num-cpus", "2")
    assert "reserves" in line and "has 2" in line
    runs.write_text("a file")
    line = fails(capfd, "train", "--logdir", str(runs), "--task", "pendulum")
    assert "exists and is not a directory" in line


def test_an_evaluator_env_that_cannot_take_the_policy_is_refused_before_ray(
    tmp_path: Path, capfd: pytest.CaptureFixture
) -> None:
    runs = tmp_path / "runs"
    # Other spaces: Pendulum's policy maps 3 observations to 1 action, MountainCar's env has 2.
    line = train_fails(capfd, runs, "--task", "pendulum", "--eval-env-id",
                       "MountainCarContinuous-v0")  # fmt: skip
    assert line.startswith("error: --eval-env-id (MountainCarContinuous-v0): its observation "
                           "space is Box("), line  # fmt: skip
    assert "the task Pendulum-v1's is Box(" in line and "unchanged" in line
    # Not registered: the task's own wording, with its nearest name.
    line = train_fails(capfd, runs, "--task", "pendulum", "--eval-env-id", "Pendulm-v1")
    assert line.startswith("error: --eval-env-id (Pendulm-v1): unknown task"), line
    assert "Pendulum-v1" in line
    # Nothing to play it without an evaluator.
    line = train_fails(capfd, runs, "--task", "pendulum", "--no-evaluator", "--eval-env-id",
                       "Pendulum-v1")  # fmt: skip
    assert line == "error: --eval-env-id 'Pendulum-v1': expected null without evaluator"
    # The same spaces pass: a short name resolves to its env.
    from robogym_ray.config import FLAGS
    from robogym_ray.experience.rollout import make_gym_env

    probe = make_gym_env("RoboGymRay/IsaacReachIsaacRewardUR10Sim-v0")()
    try:
        got = run_setup.check_eval_env("isaac-reach-ur10", probe, "the variant", FLAGS)
    finally:
        probe.close()
    assert got == "RoboGymRay/IsaacReachUR10Sim-v0"


def test_outputs_under_a_file_are_refused_before_the_work(
    tmp_path: Path, capfd: pytest.CaptureFixture
) -> None:
    """``--out notes.txt/eval`` used to fail in mkdir after every episode had run."""
    notes = tmp_path / "notes.txt"
    notes.write_text("keep")
    good = learner_file(tmp_path / "learner.pt", 20, 2, policy_hidden=(16,), critic_hidden=(16,))
    line = fails(capfd, "evaluate", str(good), "--out", str(notes / "eval"))
    assert line.endswith(f"{notes} exists and is not a directory") and "--out" in line
    line = fails(capfd, "export", str(good), str(notes / "sub" / "policy.ts"))
    assert line.endswith(f"{notes} exists and is not a directory")
    line = fails(capfd, "train", "--logdir", str(notes / "runs"), "--task", "pendulum")
    assert line.endswith(f"{notes} exists and is not a directory")
    assert notes.read_text() == "keep"


def test_one_line_in_a_fresh_process(tmp_path: Path) -> None:
    """The whole process: no torch warning or pybullet banner before the error line."""
    source = tmp_path / "learner.pt"
    source.touch()
    out = children.run(
        [sys.executable, "-m", "robogym_ray.cli", "train", "--init-from", str(source),
         "--logdir", str(tmp_path / "runs")],
        capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    assert out.returncode == 2
    assert out.stderr == f"error: cannot read checkpoint {source}: empty file (0 bytes)\n"
    assert not (tmp_path / "runs").exists()


def test_nan_from_the_command_line_is_refused(tmp_path: Path, capfd: pytest.CaptureFixture) -> None:
    # argparse's float() takes "nan", and NaN passes any `x > 0` written as `not x <= 0`.
    line = train_fails(capfd, tmp_path / "runs", "--max-wall-s", "nan")
    assert line == "error: --max-wall-s nan: expected a number (not NaN) or null"


def test_a_bad_value_names_its_flag_or_its_file(
    tmp_path: Path, capfd: pytest.CaptureFixture
) -> None:
    """A value given as a flag is named by its flag (it read TrainConfig.workers=0); one from a
    config file keeps naming the file and the field."""
    runs = tmp_path / "runs"
    expected = "expected >= 1 with no real robot"
    assert train_fails(capfd, runs, "--workers", "0") == f"error: --workers 0: {expected}"
    line = train_fails(capfd, runs, "--learner-cpus", "0")
    assert line == "error: --learner-cpus 0.0: expected > 0"
    line = train_fails(capfd, runs, "--emulated-workers", "1", "--emu-latency-ticks", "-1")
    assert line == "error: --emu-latency-ticks -1: expected >= 0"
    config = tmp_path / "c.json"
    config.write_text(json.dumps({"train": {"workers": 0}}))
    line = train_fails(capfd, runs, "--config", str(config))
    assert line == f"error: {config}: invalid TrainConfig: TrainConfig.workers=0; {expected}"
    line = fails(capfd, "serve", "--emulate-hardware", "--emu-latency-ticks", "-1")
    assert line == "error: --emu-latency-ticks -1: expected >= 0"  # other commands' flags too


def test_resume_needs_the_run_name_to_resume(tmp_path: Path, capfd: pytest.CaptureFixture) -> None:
    """Without --run-name, --resume would name a new, empty folder (a default name)."""
    line = train_fails(capfd, tmp_path / "runs", "--task", "pendulum", "--resume")
    assert line == ("error: --resume without --run-name: expected the --run-name of the run to "
                    "resume (without one, a new, empty folder)")  # fmt: skip


def test_a_storage_that_cannot_be_written_is_refused_before_ray(
    tmp_path: Path, capfd: pytest.CaptureFixture
) -> None:
    """It failed after Ray had started (12 s); now in one line before, leaving nothing."""
    line = train_fails(capfd, tmp_path / "runs", "--task", "pendulum", "--storage", "/proc/x")
    assert line == "error: --storage /proc/x: cannot write there (no such file or directory)"
    line = train_fails(capfd, tmp_path / "runs", "--task", "pendulum", "--logdir", "/proc/x")
    assert line == "error: --logdir /proc/x: cannot write there (no such file or directory)"


def test_a_run_refused_after_the_storage_check_leaves_no_folder(
    tmp_path: Path, capfd: pytest.CaptureFixture
) -> None:
    """The storage check writes a file at the run root, making the folders it needs; a check
    after it that refuses the run (networks torch cannot make) leaves none of them behind."""
    config = tmp_path / "bad.json"
    config.write_text(json.dumps({"train": {"task": "pendulum"}, "d4pg": {"policy_hidden": [-5]}}))
    logdir = tmp_path / "new" / "runs"
    line = fails(capfd, "train", "--logdir", str(logdir), "--config", str(config))
    assert line.startswith("error: d4pg: no networks of policy_hidden=(-5,)")
    with pytest.raises(ConfigError, match="no networks"):
        robogym_ray.train(config, logdir=str(logdir))
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.json"]


def test_the_python_entrys_errors_name_its_keywords(tmp_path: Path) -> None:
    """``robogym_ray.train``'s errors name what its caller wrote (``workers=64``,
    ``resume=True``, ``run_name=``), not the command line's flags."""
    runs = tmp_path / "runs"

    def refused(**given: object) -> str:
        with pytest.raises(ConfigError) as info:
            robogym_ray.train(task="pendulum", logdir=str(runs), **given)
        assert "--" not in str(info.value), info.value
        return str(info.value)

    assert refused(workers=64, num_cpus=2).endswith(
        "cluster has 2: lower workers=64, worker_cpus=0.25, server_cpus=0.2 or learner_cpus=0.5, "
        "or add nodes"
    )
    assert refused(resume=True) == (
        "resume=True without run_name=: expected the run_name= of the run to resume (without "
        "one, a new, empty folder)"
    )
    (runs / "taken").mkdir(parents=True)
    (runs / "taken" / "config.json").write_text("{}")
    assert refused(run_name="taken") == (
        f"run folder {runs / 'taken'} holds a run already: pass resume=True to continue it, or "
        "another run_name= (leave it out for a new name each run)"
    )
    line = refused(run_name="none", resume=True)
    assert line == f"resume=True: {runs / 'none'} has no checkpoint to continue from"
    line = refused(storage="/proc/x")
    assert line == "storage /proc/x: cannot write there (no such file or directory)"
    # TrainConfig's own checks and the ones before Ray starts, worded for a Python call too.
    assert "TrainConfig.real_robot=('nohost',); expected HOST:PORT" in refused(
        real_robot=["nohost"]
    )
    assert "TrainConfig.address='nohost'; expected null, auto" in refused(address="nohost")
    assert "TrainConfig.tls_ca='ca.pem'; expected only with a real robot" in refused(
        tls_ca="ca.pem"
    )
    ca = tmp_path / "missing.pem"
    line = refused(real_robot=["127.0.0.1:1"], tls_ca=str(ca))
    assert line.startswith(f"tls_ca {ca}: cannot read it"), line
    line = refused(emulated_workers=1)
    assert line == "emulated_workers=1 needs a robot task; Pendulum-v1 has none", line
