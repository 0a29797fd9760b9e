"""How a run ended (issue 53): ``summary.json``'s ``ended_by`` and ``resumed``, and the short
summary's first line; older summaries still read as before."""

from __future__ import annotations

from robogym_ray.training.command import summary_text
from robogym_ray.training.ending import end_reason

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
    lines = short(ended_by="max_wall_s", resumed=True)
    assert lines[0] == (
        f"Trained Pendulum-v1 (resumed): {done}; ended at --max-wall-s, before --total-steps."
    )
    stopped = short(ended="stopped", stopped_by="SIGINT", ended_by="SIGINT")
    assert stopped[0] == f"Stopped early by SIGINT: Pendulum-v1 trained {done}."
