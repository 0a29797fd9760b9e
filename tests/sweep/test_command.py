"""``robogym-ray sweep`` as a user meets it, without Ray: its ``--help``, the record a sweep
writes (its space and how many trials it makes), and ``--resume`` of a sweep that finished."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from robogym_ray.cli import main
from robogym_ray.sweep.config import SweepConfig
from robogym_ray.sweep.plan import STATE, SWEEP_RECORD, plan_sweep


def test_help_lists_the_summary_action_once(capsys: pytest.CaptureFixture) -> None:
    with pytest.raises(SystemExit):
        main(["sweep", "--help"])
    text = capsys.readouterr().out
    assert text.count("summary NAME") == 2  # the usage line and its one entry
    assert "  summary NAME          the sweep's table and figure" in text
    assert "\n    summary" not in text  # argparse's second listing of the same action


def test_the_record_holds_the_space_and_the_trial_count(tmp_path: Path) -> None:
    cfg = SweepConfig(
        set=("task=pendulum", "total_steps=100"), storage=str(tmp_path), name="s", samples=2,
        space=("d4pg.sigma=0.2,0.4", "sigma_min=uniform(0.05, 0.1)",
               'd4pg.policy_hidden=[[64],[32,32]]'), seeds=(0, 1, 2),
    )  # fmt: skip
    plan = plan_sweep(cfg)
    assert plan.trial_count() == 2 * 2 * 2 * 3  # grids and seeds, twice; a draw adds none
    record = json.loads(plan.record(["--name", "s"]))
    assert record["trials"] == 24
    assert record["space"] == [
        "d4pg.sigma=[0.2, 0.4]",
        "train.sigma_min=uniform(0.05, 0.1)",
        "d4pg.policy_hidden=[[64], [32, 32]]",
        "train.seed=[0, 1, 2]",
    ]


@pytest.mark.usefixtures("ray_must_not_start")
def test_resuming_a_finished_sweep_says_so_and_starts_nothing(
    tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    sweep = tmp_path / "done"
    sweep.mkdir()
    (sweep / STATE).write_bytes(b"")  # Tune's state: the folder holds a sweep
    record = {"name": "done", "metric": "eval/success_rate", "trials": 4, "finished": True}
    (sweep / SWEEP_RECORD).write_text(json.dumps(record))
    assert main(["sweep", "--resume", "done", "--storage", str(tmp_path)]) == 0
    out = capsys.readouterr().out.strip()
    assert out == (
        f"sweep {sweep} finished, nothing to resume (its table: "
        f"robogym-ray sweep summary done --storage {tmp_path})"
    )
