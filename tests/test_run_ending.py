"""How a run ended and what it adds up to over its parts: ``summary.json``'s
``ended_by``, ``resumed``, ``this_part`` and ``whole_run``, and the short summary's lines; older
summaries still read as before."""

from __future__ import annotations

from robogym_ray.training.command import summary_text
from robogym_ray.training.ending import end_reason, run_parts

PART = {"env_steps": 1200, "episodes": 6, "learner_steps": 300, "wall_s": 9.5}


def test_why_a_run_ended() -> None:
    def why(**given: object) -> str:
        facts = dict(failed=False, stopped_by=None, env_steps=100, total_steps=100,
                     out_of_time=False) | given  # fmt: skip
        return end_reason(**facts)  # type: ignore[arg-type]

    assert why() == "total_steps"
    assert why(env_steps=40, out_of_time=True) == "max_wall_s"
    assert why(out_of_time=True) == "total_steps"  # the steps were there first
    assert why(env_steps=40, stopped_by="SIGINT") == "SIGINT"
    assert why(failed=True, stopped_by="SIGTERM") == "error"
    assert why(env_steps=40) == "no_workers"
    # No step cap (a run given only --max-wall-s): only the time, a signal or no worker ends it.
    assert why(env_steps=10**9, total_steps=None, out_of_time=True) == "max_wall_s"
    assert why(env_steps=10**9, total_steps=None) == "no_workers"


def test_a_first_part_is_the_whole_run() -> None:
    this, whole = run_parts(PART, None, resumed=False)
    assert this == {"part": 1, **PART}
    assert whole == {"parts": 1, **PART, "complete": True}


def test_a_resumed_part_adds_to_the_earlier_parts() -> None:
    _, first = run_parts(PART, None, resumed=False)
    more = {"env_steps": 800, "episodes": 4, "learner_steps": 200, "wall_s": 5.3}
    this, whole = run_parts(more, {"env_steps": 1200, "whole_run": first}, resumed=True)
    assert this == {"part": 2, **more}
    assert whole == {"parts": 2, "env_steps": 2000, "episodes": 10, "learner_steps": 500,
                     "wall_s": 14.8, "complete": True}  # fmt: skip
    # A summary from before parts were counted: one part, its own counts.
    _, whole = run_parts(more, {**PART, "task": "Pendulum-v1"}, resumed=True)
    assert (whole["parts"], whole["env_steps"], whole["learner_steps"]) == (2, 2000, 500)
    # The earlier part wrote no summary (killed): its learner steps are known, nothing else.
    this, whole = run_parts(more, None, resumed=True, first_learner_step=700)
    assert this["part"] == 2 and whole["learner_steps"] == 900 and whole["env_steps"] == 800
    assert whole["complete"] is False


def test_a_killed_part_is_counted_from_the_checkpoint_its_caller_recorded() -> None:
    # A Tune trial's record (env steps, episodes, wall s, learner steps at its checkpoint);
    # the learner restored a newer checkpoint of its own: its step, 520, is the one counted.
    record = {"env_steps": 1528, "episodes": 7, "learner_steps": 400, "wall_s": 6.1, "parts": 1}
    more = {"env_steps": 4472, "episodes": 22, "learner_steps": 300, "wall_s": 12.0}
    this, whole = run_parts(more, None, resumed=True, first_learner_step=520, checkpointed=record)
    assert this == {"part": 2, **more}
    assert whole == {"parts": 2, "env_steps": 6000, "episodes": 29, "learner_steps": 820,
                     "wall_s": 18.1, "complete": True}  # fmt: skip
    _, whole = run_parts(more, None, resumed=True, first_learner_step=380, checkpointed=record)
    assert whole["learner_steps"] == 380 + 300  # not the record's 400: taken after 380 was kept
    # A summary the earlier part wrote is the earlier part's own word: it comes first.
    _, first = run_parts(PART, None, resumed=False)
    _, whole = run_parts(more, {"whole_run": first}, resumed=True, checkpointed=record)
    assert whole["env_steps"] == 1200 + 4472


def short(**facts: object) -> list[str]:
    summary = {"task": "Pendulum-v1", **PART, "restarts": {}, "dropped_steps": 0,
               "robot_errors": 0, "checkpoint": "/r/p/checkpoints/learner.pt",
               "logdir": "/r/p", "ended": "completed", **facts}  # fmt: skip
    return summary_text(summary).splitlines()


def test_the_short_summary_says_why_the_run_ended_and_that_it_resumed() -> None:
    done = "1,200 env steps, 6 episodes, 300 learner steps in 9.5 s"
    assert short()[0] == f"Trained Pendulum-v1: {done}."  # an older summary, as before
    ended = short(ended_by="total_steps")[0]
    assert ended == f"Trained Pendulum-v1: {done}; ended at --total-steps."
    this, whole = run_parts(PART, None, resumed=False)
    more = {"env_steps": 800, "episodes": 4, "learner_steps": 200, "wall_s": 5.3}
    this, whole = run_parts(more, {"whole_run": whole}, resumed=True)
    lines = short(ended_by="max_wall_s", resumed=True, this_part=this, whole_run=whole,
                  env_steps=800, learner_steps=500)  # fmt: skip
    assert lines[0] == (
        "Trained Pendulum-v1 part 2 (resumed): 800 env steps, 4 episodes, "
        "200 learner steps in 5.3 s; ended at --max-wall-s, before --total-steps."
    )
    assert lines[1] == ("  whole run:   2 parts, 2,000 env steps, 10 episodes, 500 learner steps "
                        "in 14.8 s")  # fmt: skip
    stopped = short(ended="stopped", stopped_by="SIGINT", ended_by="SIGINT")
    assert stopped[0] == f"Stopped early by SIGINT: Pendulum-v1 trained {done}."


def test_a_run_with_no_step_cap_ended_at_its_time_not_before_a_total() -> None:
    done = "1,200 env steps, 6 episodes, 300 learner steps in 9.5 s"
    line = short(ended_by="max_wall_s", total_steps=None)[0]
    assert line == f"Trained Pendulum-v1: {done}; ended at --max-wall-s."
    capped = short(ended_by="max_wall_s", total_steps=5000)[0]
    assert capped.endswith("; ended at --max-wall-s, before --total-steps.")


def test_an_interval_evaluators_figures_say_they_span_more_of_the_run() -> None:
    """An evaluator started every 15 s plays its last 100 episodes over much of the run, by
    older policies: its figures are not comparable with a back-to-back evaluator's."""
    history = [{"wall_s": 15.0 * (i + 1)} for i in range(200)]  # one episode per call
    rates = {"eval/success_rate": 0.9, "eval/collision_rate": 0.0, "eval/timeout_rate": 0.1}
    facts = {**rates, "eval/episodes": 200, "eval_history": history, "wall_s": 3000.0}
    lines = short(**facts, eval_interval_s=15.0)
    at = next(i for i, line in enumerate(lines) if "greedy evaluation" in line)
    assert lines[at + 1] == (
        "    (evaluator calls every 15 s, these episodes over the last 25.0 min: not comparable "
        "with a back-to-back evaluator's)"
    )
    assert not any("comparable" in line for line in short(**facts, eval_interval_s=0.0))
    assert not any("comparable" in line for line in short(**facts))  # an older summary
