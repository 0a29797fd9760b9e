"""Isaac Lab's exported policies on our robots, and our own policies as ONNX.

The policy files are made with the structure Isaac Lab's rsl_rl exporter gives them, by
``robogym_ray.isaac_lab_sample`` (``robogym-ray isaac-lab-sample``, which a user without Isaac
Lab runs too): no Isaac Lab needed. They run through ``run-policy --isaac-lab`` on the Sim id
and on an emulated robot behind ``robogym-ray serve``.
"""

from __future__ import annotations

import json
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
import torch
from torch import nn

from robogym_ray.cli import main as cli_main
from robogym_ray.evaluation import emulated_server
from robogym_ray.export import ONNX_FORMAT, export_policy, load_exported, load_policy
from robogym_ray.isaac_lab_sample import write_sample
from robogym_ray.robots.serve import serve_process
from tests.experiments.conftest import POSITIONING, save_learner

pytest.importorskip("onnxruntime")

UR10 = "RoboGymRay/IsaacReachUR10Sim-v0"
PANDA = "RoboGymRay/IsaacReachPandaSim-v0"


class RecurrentExporter(nn.Module):
    """The shape of rsl_rl's recurrent export: ``actor(rnn(obs))``."""

    def __init__(self) -> None:
        super().__init__()
        self.rnn = nn.GRU(25, 32)
        self.actor = nn.Sequential(nn.Linear(32, 6))

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        out, _ = self.rnn(x.unsqueeze(0))
        return self.actor(out.squeeze(0))


@pytest.fixture(scope="module")
def ur10_files(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path | None, nn.Module]:
    return write_sample(tmp_path_factory.mktemp("isaac") / "exported", 25, 6)


def run_policy(capsys: pytest.CaptureFixture, *argv: str) -> dict:
    assert cli_main(["run-policy", *argv]) == 0
    return json.loads(capsys.readouterr().out.strip().splitlines()[-1])


def test_both_files_run_on_the_sim_id_and_act_alike(ur10_files, tmp_path, capsys) -> None:
    pt, onnx, module = ur10_files
    runs = {}
    for path in (pt, onnx):
        out = tmp_path / path.suffix[1:]
        summary = run_policy(capsys, "--isaac-lab", str(path), "--env-id", UR10,
                             "--episodes", "2", "--max-steps", "15", "--out", str(out))  # fmt: skip
        assert summary["env_id"] == UR10 and summary["n_episodes"] == 2
        # What the runner prints: success and the end effector's final errors.
        assert 0.0 <= summary["rates"]["success_rate"] <= 1.0
        assert summary["mean_position_error"] > 0 and summary["mean_rotation_error"] >= 0
        runs[path.suffix] = json.loads((out / "evaluation.json").read_text())["episodes"]
    # The two files are one network: the same seeded episodes end the same way.
    for a, b in zip(runs[".pt"], runs[".onnx"], strict=True):
        assert (a["seed"], a["final_status"], a["length"]) == (b["seed"], b["final_status"],
                                                               b["length"])  # fmt: skip
        assert a["position_error"] == pytest.approx(b["position_error"], abs=1e-4)


def test_raw_actions_reach_the_env_in_its_own_units(ur10_files) -> None:
    """The runner's [-1, 1] mapping undoes the env's: the env receives the network's output."""
    import gymnasium as gym

    from robogym_ray.isaac_lab import IsaacLabPolicy
    from robogym_ray.learner.behaviour import to_env_action

    pt, onnx, module = ur10_files
    env = gym.make(UR10)
    try:
        obs, _ = env.reset(seed=0)
        low, high = env.action_space.low, env.action_space.high
        with torch.no_grad():
            raw = module(torch.as_tensor(obs[None])).numpy()[0]
        for path in (pt, onnx):
            unit = IsaacLabPolicy(path).unit_policy(env)(obs)
            np.testing.assert_allclose(to_env_action(unit, low, high), raw, atol=1e-5)
    finally:
        env.close()


@pytest.fixture
def emulated_isaac_ur10() -> Iterator[str]:
    """``robogym-ray serve --emulate-hardware`` with IsaacReachUR10's robot, table and frame."""
    with emulated_server(UR10, seed=1) as address:
        yield address


def test_both_files_drive_an_emulated_robot(ur10_files, emulated_isaac_ur10, capsys) -> None:
    pt, onnx, _ = ur10_files
    for path in (pt, onnx):
        summary = run_policy(capsys, "--isaac-lab", str(path), "--env-id", UR10,
                             "--rs-address", emulated_isaac_ur10, "--episodes", "1",
                             "--max-steps", "6")  # fmt: skip
        assert summary["env_id"] == "RoboGymRay/IsaacReachUR10Rob-v0"
        assert summary["rs_address"] == emulated_isaac_ur10 and summary["n_episodes"] == 1
        # Real-time pacing at the task's 30 Hz: 6 actions take at least 0.2 s.
        assert summary["wall_s"] >= 0.2


def one_error_line(capfd: pytest.CaptureFixture, *argv: str) -> str:
    capfd.readouterr()
    assert cli_main(list(argv)) == 2
    lines = capfd.readouterr().err.splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), lines
    return lines[0]


def test_files_of_the_wrong_kind_or_shape_are_refused(ur10_files, tmp_path, capfd) -> None:
    pt, onnx, _ = ur10_files
    for path in (pt, onnx):  # the UR10's 25 -> 6 policy on the Panda's 32 -> 7 task
        line = one_error_line(capfd, "run-policy", "--isaac-lab", str(path), "--env-id", PANDA)
        assert "maps 25 observations to 6 actions" in line and "has 32 and 7" in line
    junk = tmp_path / "policy.pt"
    junk.write_bytes(bytes(range(256)) * 8)
    assert "not a TorchScript file" in one_error_line(
        capfd, "run-policy", "--isaac-lab", str(junk), "--env-id", UR10)  # fmt: skip
    junk_onnx = tmp_path / "policy.onnx"
    junk_onnx.write_bytes(bytes(range(256)) * 8)
    assert "not an ONNX model" in one_error_line(
        capfd, "run-policy", "--isaac-lab", str(junk_onnx), "--env-id", UR10)  # fmt: skip
    plain = tmp_path / "plain.pt"  # TorchScript, but no actor: not an rsl_rl export
    torch.jit.script(nn.Sequential(nn.Linear(25, 6))).save(str(plain))
    line = one_error_line(capfd, "run-policy", "--isaac-lab", str(plain), "--env-id", UR10)
    assert "not an rsl_rl export" in line
    # What it has, and the layout expected instead, with the command that writes one.
    assert "(its parameters: 0.weight, 0.bias)" in line
    assert "parameters actor.<i>.weight in order" in line and "isaac-lab-sample DIR" in line
    recurrent = tmp_path / "recurrent.pt"  # rsl_rl's recurrent export: actor after an rnn
    torch.jit.script(RecurrentExporter()).save(str(recurrent))
    assert "a recurrent rsl_rl policy" in one_error_line(
        capfd, "run-policy", "--isaac-lab", str(recurrent), "--env-id", UR10)  # fmt: skip
    other = tmp_path / "policy.zip"
    other.write_bytes(b"x")
    assert "policy.pt (TorchScript) or policy.onnx" in one_error_line(
        capfd, "evaluate", "--isaac-lab", str(other), "--env-id", UR10)  # fmt: skip
    assert "needs --env-id" in one_error_line(capfd, "evaluate", "--isaac-lab", str(pt))


def test_the_sample_command_writes_both_files_for_an_envs_sizes(tmp_path, capfd) -> None:
    """``robogym-ray isaac-lab-sample``: both files in rsl_rl's layout, as the loader reads
    them, for the sizes of the env given; an export already in the folder is kept."""
    from robogym_ray.isaac_lab import IsaacLabPolicy

    capfd.readouterr()
    assert cli_main(["isaac-lab-sample", str(tmp_path / "exported"), "--env-id", PANDA]) == 0
    out = json.loads(capfd.readouterr().out.strip().splitlines()[-1])
    assert (out["obs_dim"], out["act_dim"], out["trained"]) == (32, 7, False)
    obs = np.random.default_rng(0).normal(size=32).astype(np.float32)
    actions = []
    for key in ("policy_pt", "policy_onnx"):
        policy = IsaacLabPolicy(out[key])
        assert (policy.obs_dim, policy.act_dim) == (32, 7)
        actions.append(policy(obs))
    np.testing.assert_allclose(actions[0], actions[1], atol=1e-5)  # one network in two files
    before = (tmp_path / "exported" / "policy.pt").read_bytes()
    line = one_error_line(capfd, "isaac-lab-sample", str(tmp_path / "exported"))
    assert "policy.pt and policy.onnx already there" in line
    assert (tmp_path / "exported" / "policy.pt").read_bytes() == before


def test_the_pages_sample_command_writes_the_files_its_steps_run(tmp_path, monkeypatch) -> None:
    (argv,) = doc_commands("isaac-lab-sample")  # docs/isaac-lab.md, as written
    monkeypatch.chdir(tmp_path)
    assert cli_main(["isaac-lab-sample", *argv]) == 0
    assert (tmp_path / "exported" / "policy.pt").is_file()
    assert (tmp_path / "exported" / "policy.onnx").is_file()


def test_our_onnx_export_acts_like_its_torchscript_twin(tmp_path) -> None:
    save_learner(tmp_path / "learner.pt", 15, 6)
    export_policy(tmp_path / "learner.pt", tmp_path / "policy.pt", env_id=POSITIONING)
    info = export_policy(tmp_path / "learner.pt", tmp_path / "policy.onnx", env_id=POSITIONING)
    assert info.format == ONNX_FORMAT
    scripted, _ = load_exported(tmp_path / "policy.pt")
    onnx, loaded = load_exported(tmp_path / "policy.onnx")
    assert loaded == info
    obs = np.random.default_rng(0).normal(scale=2.0, size=(1000, 15)).astype(np.float32)
    with torch.no_grad():
        expected = scripted(torch.from_numpy(obs)).numpy()
    np.testing.assert_allclose(onnx(obs), expected, rtol=0, atol=1e-5)  # any batch size
    one = load_policy(tmp_path / "policy.onnx")  # one observation at a time, as evaluate does
    np.testing.assert_allclose(one(obs[7]), expected[7], rtol=0, atol=1e-5)


@pytest.mark.ray
@pytest.mark.slow
@pytest.mark.usefixtures("ray_cluster")
def test_the_robot_is_driven_through_the_real_robot_safety_filter(
    ur10_files, emulated_isaac_ur10
) -> None:
    from robogym_ray.evaluation import EvaluationConfig, evaluate

    pt, _, _ = ur10_files
    cfg = EvaluationConfig(env_id=UR10, rs_address=emulated_isaac_ur10, episodes=1, max_steps=4,
                           via_actor=True, isaac_lab=True)  # fmt: skip
    result = evaluate(pt, cfg)
    assert result.env_id == "RoboGymRay/IsaacReachUR10Rob-v0" and result.episodes[0].length == 4


def doc_commands(program: str, part: int = 0) -> list[list[str]]:
    """docs/isaac-lab.md's ``robogym-ray PROGRAM ...`` command lines, arguments after it, in
    the page's ``part``-th top-level section (0: robo-gym 2.1.0's reach, 1: Isaac Lab 3's)."""
    import re
    import shlex

    page = (Path(__file__).resolve().parents[2] / "docs" / "isaac-lab.md").read_text()
    text = page.split("\n# ")[part]
    code = "\n".join(re.findall(r"```bash\n(.*?)```", text, re.S)).replace("\\\n", " ")
    commands = [shlex.split(line, comments=True) for line in code.splitlines()]
    return [c[2:] for c in commands if c[:2] == ["robogym-ray", program]]


def run_page_commands(
    part: int, policies: tuple[Path, Path], tmp_path: Path, capsys, extra: dict | None = None
) -> None:
    """Every robogym-ray command of the page's ``part`` as written: the two policy files for
    POLICY in turn, ``extra`` for other placeholders, a free port for the server, folders of
    its own and one short episode each."""
    (serve,) = doc_commands("serve", part)
    with serve_process(["0" if a == "50051" else a for a in serve]) as address:
        runs = [("run-policy", a) for a in doc_commands("run-policy", part)]
        runs += [("evaluate", a) for a in doc_commands("evaluate", part)]
        assert len(runs) == 4
        for k, (program, argv) in enumerate(runs):
            swap = {"POLICY": str(policies[k % 2]), "ROBOT:50051": address,
                    "127.0.0.1:50051": address, **(extra or {})}  # fmt: skip
            argv = [swap.get(a, str(tmp_path / a) if a.startswith("ev-") else a) for a in argv]
            if "--token" in argv:  # the emulated server wants none
                del argv[argv.index("--token") : argv.index("--token") + 2]
            argv[argv.index("--episodes") + 1] = "1"
            assert cli_main([program, *argv, "--max-steps", "3"]) == 0, argv
            summary = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
            assert summary["n_episodes"] == 1


@pytest.mark.ray
@pytest.mark.slow
@pytest.mark.usefixtures("ray_cluster")
def test_the_pages_commands_run(ur10_files, tmp_path, capsys) -> None:
    """Every robogym-ray command of docs/isaac-lab.md's robo-gym 2.1.0 part (run_page_commands)."""
    pt, onnx, _ = ur10_files
    run_page_commands(0, (pt, onnx), tmp_path, capsys)
