"""Sweeps on a real local Ray and Tune (Pendulum, one worker per trial, seconds each): trials
two at a time with their files under the sweep's storage, ASHA stopping the trials a setting
makes worse, a sweep whose driver was SIGKILLed resumed from its trials' checkpoints, and a
trial whose actors need more than its bundles refused before it starts."""

from __future__ import annotations

import json
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import pytest
import ray

from robogym_ray import children
from robogym_ray.cli import main

pytestmark = [pytest.mark.ray, pytest.mark.usefixtures("ray_cluster")]

# One worker of four envs, no video or timed snapshots, small networks and batches: a trial
# is its actors' start-up and a few hundred Pendulum steps; the learner steps from 100
# transitions on (min_replay_size), one step per env step.
BASE = ["--set", "task=pendulum", "workers=1", "envs_per_worker=4", "random_steps=100",
        "final_eval_episodes=1", "video_interval_s=0", "policy_snapshot_every_s=0",
        "d4pg.min_replay_size=100", "d4pg.policy_hidden=[32,32]", "d4pg.critic_hidden=[32,32]",
        "d4pg.batch_size=32", "d4pg.samples_per_insert=32"]  # fmt: skip


def trial_results(sweep: Path) -> dict[str, list[dict[str, Any]]]:
    """Tune's results of each trial of the sweep in ``sweep``, by trial folder."""
    return {
        d.name: [json.loads(line) for line in (d / "result.json").read_text().splitlines()]
        for d in sorted(sweep.iterdir())
        if (d / "result.json").is_file()
    }


def run_summaries(sweep: Path) -> dict[str, dict[str, Any]]:
    return {d.name: json.loads((d / "summary.json").read_text())
            for d in sorted((sweep / "runs").iterdir())}  # fmt: skip


def restorable(sweep: Path) -> int:
    """Trials of the sweep in ``sweep`` whose checkpoint the experiment state Tune last saved
    holds, its folder on disk: those ``--resume`` goes on from."""
    from ray.tune import ExperimentAnalysis

    try:
        trials = ExperimentAnalysis(str(sweep)).trials
    except (ValueError, OSError):  # no state saved yet, or caught while it is written
        return 0
    return sum(t.checkpoint is not None and Path(t.checkpoint.path).is_dir() for t in trials)


def test_four_trials_two_at_a_time_and_asha_stops_the_worse(
    tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    # ASHA counts work, not seconds: --time-attr env_steps, rungs at 400, 800, 1,600 and 3,200
    # env steps, comparing learner steps. A trial with min_replay_size=100000 never takes a
    # learner step; one with 100 has taken some by 400 env steps on any machine (it learns
    # from 100 transitions on, one step per eight inserted, and the driver's count is at most
    # two calls behind). Grid order: good s0, worse s0, good s1, worse s1; the last starts
    # after two have ended, one of them at least a good one, recorded at every rung. Each
    # trial reports every 100 env steps (--report-every-steps), not only at its evaluator's
    # windows, which may start seconds after its worker: so the last one's result at 400 env
    # steps stops it, however late its evaluator. A worse trial takes no learner step and
    # runs fast: its 3,600 steps after the rung leave Tune time to stop it before its end.
    # ASHA may stop a good one too (one that trails the median).
    argv = [*BASE, "envs_per_worker=1", "d4pg.samples_per_insert=4", "total_steps=4000",
            "--space", "d4pg.min_replay_size=100,100000", "--seeds", "0", "1",
            "--max-concurrent", "2", "--scheduler", "asha", "--metric", "learner_steps",
            "--time-attr", "env_steps", "--grace-period", "400", "--report-every-steps", "100",
            "--storage", str(tmp_path), "--name", "four"]  # fmt: skip
    assert main(["sweep", *argv]) == 0
    sweep = tmp_path / "four"
    # The command main() was given, not this process's sys.argv (pytest's).
    record = json.loads((sweep / "sweep.json").read_text())
    assert record["command"] == ["robogym-ray", "sweep", *argv]
    results, runs = trial_results(sweep), run_summaries(sweep)
    assert len(results) == 4 and len(runs) == 4
    for rows in results.values():  # results between windows, marked so
        assert any(r.get("between_windows") for r in rows), rows
    for run in runs.values():  # every trial's own files under the sweep's storage
        assert Path(run["logdir"]).parent == sweep / "runs"
        assert Path(run["checkpoint"]).is_file()
    # Never more than two at a time: from each run's start (config.json) to its end
    # (summary.json). Not that two did run together: on a slow machine one trial may end
    # before the other has written its first file, which says nothing about the cap.
    spans = [((sweep / "runs" / n / "config.json").stat().st_mtime,
              (sweep / "runs" / n / "summary.json").stat().st_mtime) for n in runs]  # fmt: skip
    overlaps = [sum(a <= t < b for a, b in spans) for t, _ in spans]
    assert max(overlaps) <= 2
    config = {n: json.loads((sweep / "runs" / n / "config.json").read_text()) for n in runs}
    worse = [r for n, r in runs.items() if config[n]["d4pg"]["min_replay_size"] == 100000]
    assert len(worse) == 2 and all(r["learner_steps"] == 0 for r in worse)
    ends = [(r["ended"], r["env_steps"]) for r in worse]
    assert any(ended == "stopped" and steps < 4000 for ended, steps in ends), ends
    for run in (r for r in runs.values() if r["ended"] == "stopped"):
        # ended as a stopped run ends: final checkpoint and summary
        assert run["stopped_by"] == "scheduler" and Path(run["checkpoint"]).is_file()
    table = [line for line in (sweep / "summary.md").read_text().splitlines() if line[:1] == "|"]
    assert len(table) == 2 + 4 and any("stopped (scheduler)" in line for line in table)
    assert (sweep / "curves.png").stat().st_size > 0
    # Every trial ended: the record says so, and --resume has nothing to do (no Ray start).
    assert json.loads((sweep / "sweep.json").read_text())["finished"]
    capsys.readouterr()
    assert main(["sweep", "--resume", "four", "--storage", str(tmp_path)]) == 0
    assert "finished, nothing to resume" in capsys.readouterr().out


def test_a_sweep_goes_on_from_its_checkpoints_after_its_driver_is_killed(
    tmp_path: Path,
) -> None:
    # No evaluator: the trials' results (and so their Tune checkpoints) are the ones every 100
    # env steps, on learner steps; two processes fewer to start in each half.
    argv = [*BASE, "total_steps=1000", "checkpoint_every=100", "evaluator=false",
            "--report-every-steps", "100", "--metric", "learner_steps", "--seeds", "0", "1",
            "--max-concurrent", "2", "--storage", str(tmp_path), "--name", "killed",
            "--address", ray.get_runtime_context().gcs_address]  # fmt: skip
    driver = children.popen([sys.executable, "-m", "robogym_ray.cli", "sweep", *argv],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)  # fmt: skip
    sweep = tmp_path / "killed"
    try:
        hung = time.monotonic() + 600  # a guard against a hang, not a measure of speed
        # Killed once the experiment state Tune saved (what --resume restores) holds a
        # checkpoint of each trial: a checkpoint folder on disk alone may not be in it yet.
        while restorable(sweep) < 2:
            assert driver.poll() is None, "the sweep ended before it was killed"
            assert time.monotonic() < hung, "no restorable checkpoints in 600 s"
            time.sleep(0.5)
    finally:
        driver.kill()  # SIGKILL: no Tune shutdown, no summary; its trials die with it
        driver.wait()
    assert not list((sweep / "runs").glob("*/summary.json"))
    assert "finished" not in json.loads((sweep / "sweep.json").read_text())
    assert main(["sweep", "--resume", "killed", "--storage", str(tmp_path)]) == 0
    assert json.loads((sweep / "sweep.json").read_text())["finished"]
    runs = run_summaries(sweep)
    assert len(runs) == 2
    for run in runs.values():
        assert run["ended"] == "completed" and run["resumed"]
        assert run["learner_restored_from_step"] >= 100  # from its checkpoint, not from 0
        assert 0 < run["this_part"]["env_steps"] < 1000
        # The killed part wrote no summary: the whole run counts from the trial's checkpoint.
        whole = run["whole_run"]
        assert whole["complete"] and whole["parts"] == 2, whole
        assert whole["env_steps"] >= 1000 and whole["learner_steps"] == run["learner_steps"]
        assert whole["env_steps"] > run["this_part"]["env_steps"]
    for results in trial_results(sweep).values():
        steps = [r["env_steps"] for r in results]
        assert steps[-1] >= 1000 and results[-1]["done"]


def test_a_trial_whose_actors_need_more_than_its_bundles_is_refused(tmp_path: Path) -> None:
    from ray import tune

    from robogym_ray.sweep.trial import TrainingTrial

    small = tune.PlacementGroupFactory([{"CPU": 0.1}, {"CPU": 0.5}])  # the learner's only
    tuner = tune.Tuner(
        tune.with_resources(TrainingTrial, small),
        param_space={
            "train": {"task": "pendulum", "workers": 1},
            "sweep": {"runs": str(tmp_path / "runs")},
        },  # fmt: skip
        run_config=tune.RunConfig(name="small", storage_path=str(tmp_path), verbose=0),
    )
    (result,) = tuner.fit()
    line = str(result.error).strip().splitlines()[-1]
    assert "placement group holds 0.5 CPU besides the trial's own bundle" in line
    assert "no room for the rollout worker" in line and "trial_resources" in line
    assert not (tmp_path / "runs").exists()  # refused before the run started
