"""``sweep summary``'s reading of a sweep's folder, without Ray: the best trial either way
(``--mode min``), the time-to columns, trials whose run wrote no summary, a metric that is the
same in every trial, and ``summary.md``'s space, metric and best trial beside the table."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest

from robogym_ray.cli import main
from robogym_ray.storage import RunStorage
from robogym_ray.sweep.report import Trial, best_trial, read_trials, summarize, table

ERROR = "eval/window_position_error"
RECORD = {
    "name": "s",
    "searched": ["d4pg.sigma"],
    "space": ["d4pg.sigma=[0.2, 0.4, 0.6]"],
    "metric": "eval/success_rate",
    "mode": "max",
    "scheduler": "asha",
    "time_attr": "env_steps",
    "command": ["robogym-ray", "sweep", "--space", "..."],
}


def write_sweep(
    root: Path, trials: dict[str, tuple[list[dict[str, Any]], dict[str, Any] | None]]
) -> Path:
    """A sweep folder as a run of ``sweep`` leaves it: its record, a Tune folder per trial
    with ``result.json`` (one line per result) and the trial's run folder under ``runs``
    with its ``summary.json`` (None: the run wrote none)."""
    sweep = root / "s"
    for number, (name, (results, summary)) in enumerate(trials.items()):
        run = sweep / "runs" / name
        run.mkdir(parents=True)
        if summary is not None:
            (run / "summary.json").write_text(json.dumps(summary))
        tune = sweep / f"TrainingTrial_{name}"
        tune.mkdir()
        config = {"d4pg": {"sigma": 0.2 * (number + 1)}}
        lines = [json.dumps({**r, "run": str(run), "trial_id": name, "config": config})
                 for r in results]  # fmt: skip
        (tune / "result.json").write_text("\n".join(lines) + "\n")
    (sweep / "sweep.json").write_text(json.dumps(RECORD))
    return sweep


def windows(*rates: float, metric: str = "eval/success_rate") -> list[dict[str, Any]]:
    """One result per evaluator window, a minute apart, with ``metric`` at each rate."""
    return [{"wall_s": 60.0 * (i + 1), metric: rate, "eval/return": -100.0 + 10 * i,
             "throughput/env_steps_per_s": 500.0} for i, rate in enumerate(rates)]  # fmt: skip


def test_the_best_trial_either_way() -> None:
    def trial(name: str, *errors: float) -> Trial:
        return Trial(name, {}, windows(*errors, metric=ERROR))

    trials = [trial("a", 0.09, 0.05), trial("b", 0.07, 0.02), trial("c", 0.04, 0.08)]
    best = best_trial(trials, ERROR, "min")
    assert best is not None and best.name == "b"  # the final value counts, not the best one
    best = best_trial(trials, ERROR, "max")
    assert best is not None and best.name == "c"
    assert trials[2].best(ERROR, "min") == 0.04 and trials[2].best(ERROR, "max") == 0.08
    # The run's own summary has the last word on the final value.
    trials[0].run = {ERROR: 0.01, "ended": "completed"}
    best = best_trial(trials, ERROR, "min")
    assert best is not None and best.name == "a"
    assert best_trial([Trial("d", {}, [])], ERROR, "min") is None  # nothing reported yet


def test_the_time_to_columns_are_the_first_window_at_each_rate() -> None:
    fast = Trial("fast", {"d4pg.sigma": 0.2}, windows(0.5, 0.92, 0.9, 0.97))
    slow = Trial("slow", {"d4pg.sigma": 0.4}, windows(0.3, 0.6, 0.91))
    assert (fast.time_to(0.9), fast.time_to(0.95)) == (120.0, 240.0)
    assert (slow.time_to(0.9), slow.time_to(0.95)) == (180.0, None)
    rows = table([fast, slow], "eval/success_rate", "max").splitlines()
    assert "t 90 % (min)" in rows[0] and "t 95 % (min)" in rows[0]
    assert "| fast | 0.2 | 0.970 | 0.970 | 2.000 | 4.000 | 500 |" in rows[2]
    assert "| slow | 0.4 | 0.910 | 0.910 | 3.000 | - | 500 |" in rows[3]


def test_a_trial_whose_run_wrote_no_summary(tmp_path: Path) -> None:
    done = {"ended": "stopped", "stopped_by": "scheduler", "eval/success_rate": 0.4,
            "checkpoint": "/elsewhere/learner.pt"}  # fmt: skip
    sweep = write_sweep(tmp_path, {"a": (windows(0.2, 0.5), done), "b": (windows(0.6), None)})
    trials = {t.name: t for t in read_trials(RunStorage(str(sweep)), ["d4pg.sigma"])}
    killed = trials["b"]
    assert killed.run == {} and killed.ended() == "no summary (running, or its driver died)"
    assert killed.final("eval/success_rate") == 0.6  # its last result
    assert killed.checkpoint() == str(sweep / "runs" / "b" / "checkpoints" / "learner.pt")
    assert trials["a"].ended() == "stopped (scheduler)"
    assert trials["a"].final("eval/success_rate") == 0.4  # the summary's, not the last window
    assert trials["a"].checkpoint() == "/elsewhere/learner.pt"
    assert trials["a"].settings == {"d4pg.sigma": 0.2}


def test_summary_md_holds_the_space_the_metric_and_the_best_trial(tmp_path: Path) -> None:
    sweep = write_sweep(tmp_path, {"a": (windows(0.2, 0.5), None), "b": (windows(0.6), None)})
    text = summarize("s", str(tmp_path))
    md = (sweep / "summary.md").read_text()
    checkpoint = sweep / "runs" / "b" / "checkpoints" / "learner.pt"
    best = f"best trial (eval/success_rate max): b, eval/success_rate 0.6, checkpoint {checkpoint}"
    assert md.startswith("# Sweep s\n") and best in md and text.endswith(best)
    assert "- space: d4pg.sigma=[0.2, 0.4, 0.6]" in md
    assert "- metric: eval/success_rate (max); ASHA stopped trials that trailed" in md
    assert "- command: `robogym-ray sweep --space ...`" in md
    assert sum(line.startswith("|") for line in md.splitlines()) == 2 + 2  # the table


@pytest.mark.usefixtures("ray_must_not_start")
def test_a_metric_the_same_in_every_trial_ranks_nothing(
    tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    # Pendulum has no success condition: every trial's success rate is 0.
    sweep = write_sweep(tmp_path, {"a": (windows(0.0, 0.0), None), "b": (windows(0.0), None)})
    text = summarize("s", str(tmp_path))
    line = text.splitlines()[-1]
    assert line.startswith("best trial: none: eval/success_rate is 0 in every trial")
    assert line.endswith(f"robogym-ray sweep summary s --storage {tmp_path} --metric eval/return")
    assert line in (sweep / "summary.md").read_text()
    # Ranked on the return instead (the last window's: a's is higher), from the command line.
    assert main(["sweep", "summary", "s", "--storage", str(tmp_path), "--metric",
                 "eval/return"]) == 0  # fmt: skip
    printed = capsys.readouterr().out.splitlines()[-1]
    assert printed.startswith("best trial (eval/return max): a, eval/return -90,")
