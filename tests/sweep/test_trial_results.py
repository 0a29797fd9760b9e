"""What a trial hands Tune from its run's reports, without Ray: evaluator windows, and the
results between them that ``--report-every-steps`` asks for (the counts, and the sweep's metric
as the last window left it). The training around them runs in tests/distributed/test_sweep.py."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from robogym_ray.sweep.trial import TrainingTrial, trial_setup


def trial(tmp_path: Path, metric: str) -> TrainingTrial:
    """A trial as ``setup`` leaves it before its run starts (no placement group here)."""
    t = TrainingTrial.__new__(TrainingTrial)  # Trainable.__init__ would start logging to Tune
    t.settings = trial_setup({"train": {"task": "pendulum", "checkpoint_every": 100}})
    t.runs, t.run_name, t.metric = str(tmp_path), "r", metric
    t.before = {"env_steps": 1000, "episodes": 5, "wall_s": 10.0}  # a part before this one
    t.last, t.checkpointed = {}, 0
    return t


def counts(env_steps: int, learner_steps: int) -> dict[str, Any]:
    return {"wall_s": 2.0, "env_steps": env_steps, "learner_steps": learner_steps,
            "episodes": 1, "env_steps_per_s": 100.0, "learner_steps_per_s": 10.0}  # fmt: skip


def window(env_steps: int, learner_steps: int, rate: float) -> dict[str, Any]:
    return {**counts(env_steps, learner_steps), "success_rate": rate, "return": -1.0,
            "snapshot_success_rate": 0.0, "eval_episodes": 3}  # fmt: skip


def test_an_eval_metric_is_carried_from_the_last_window_and_not_sent_before_one(
    tmp_path: Path,
) -> None:
    t = trial(tmp_path, "eval/success_rate")
    # Before any window there is no rate to send, and Tune refuses a result without its
    # metric: nothing is sent, and the checkpoint mark is left for the result that is.
    assert t._progress(counts(200, 150)) is None
    assert t.last == {} and t.checkpointed == 0
    first = t._window(window(400, 250, 0.5))
    assert first["should_checkpoint"] and first["eval/episodes"] == 3
    between = t._progress(counts(600, 320))
    assert between is not None
    assert between["eval/success_rate"] == 0.5  # the last window's
    assert between["between_windows"] and "eval/return" not in between
    assert between["env_steps"] == 1600 and between["learner_steps"] == 320  # after the part
    assert between["wall_s"] == 12.0 and between["episodes"] == 6
    assert between["should_checkpoint"]  # the learner passed its 300-step checkpoint mark
    again = t._progress(counts(800, 340))
    assert again is not None and "should_checkpoint" not in again


def test_a_count_metric_is_this_results_own(tmp_path: Path) -> None:
    t = trial(tmp_path, "learner_steps")
    assert t._progress(counts(200, 0))["learner_steps"] == 0  # sent before any window
    t._window(window(400, 250, 0.5))
    assert t._progress(counts(600, 320))["learner_steps"] == 320  # not the window's 250


def test_the_final_result_is_a_window_again_and_the_curve_skips_only_the_ones_between(
    tmp_path: Path,
) -> None:
    from robogym_ray.sweep.report import curve

    t = trial(tmp_path, "eval/success_rate")
    rows = [t._window(window(400, 250, 0.5)), t._progress(counts(600, 320))]
    summary = {"env_steps": 900, "wall_s": 3.0, "learner_steps": 400, "episodes": 2,
               "ended": "completed", "eval/success_rate": 0.75, "eval/episodes": 5}  # fmt: skip
    final = t._final(summary)
    assert "between_windows" not in final and final["done"]
    assert final["eval/success_rate"] == 0.75 and final["eval/episodes"] == 5
    rows.append(final)
    # The window and the final one, not the repeat between them; a count metric at every row.
    assert [v for _, v in curve(rows, "eval/success_rate")] == [0.5, 0.75]
    assert [v for _, v in curve(rows, "learner_steps")] == [250, 320, 400]
