"""Every run ends with an evaluation of its final policy (``EvalSchedule.final``).

A short run on a busy machine can end before the evaluator has finished one episode; the run's
summary and TensorBoard must still carry ``eval/*``. Which case a run hits depends on the
machine's speed, so each case is driven here on the real program's actors directly.
"""

from __future__ import annotations

import contextlib
import dataclasses
import os
import signal
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
import ray

from robogym_ray.robots.emulation import EmulationConfig
from robogym_ray.training.config import TrainConfig
from robogym_ray.training.evals import EvalSchedule
from robogym_ray.training.logger import RunLogger
from robogym_ray.training.presets import d4pg_for, resolve_task
from robogym_ray.training.program import Program
from robogym_ray.training.setup import run_place
from robogym_ray.training.stats import RunStats

pytestmark = [pytest.mark.ray, pytest.mark.slow, pytest.mark.usefixtures("ray_cluster")]

NAV = "RoboGymRay/ObstacleAvoidanceMir100Sim-v0"


@contextlib.contextmanager
def _program(tmp_path: Path, **cfg: object) -> Iterator[tuple[TrainConfig, Program, RunLogger]]:
    """A one-worker navigation run's program and logger, shut down and closed after."""
    config = TrainConfig(
        task=NAV, workers=1, total_steps=1000, logdir=str(tmp_path), progress=False, **cfg
    )
    preset = resolve_task(config.task)
    place = run_place(config, preset.env_id)
    program = Program(config, d4pg_for(preset, None), preset, EmulationConfig(), place)
    logger = RunLogger(program.run_dir, total=config.total_steps, progress=False)
    try:
        yield config, program, logger
    finally:
        logger.close()
        program.shutdown()


def test_a_run_whose_evaluator_finished_nothing_evaluates_its_final_policy(
    tmp_path: Path,
) -> None:
    with _program(tmp_path, run_name="final", final_eval_episodes=3) as (_, program, logger):
        run_stats = RunStats()
        schedule = EvalSchedule(program, run_stats)
        # The end of a run whose evaluator has no result yet and no call in flight.
        schedule.final(None, logger, wall_s=1.0)
        first = dict(run_stats.eval)
        assert first["eval_final_episodes"] == 3
        assert first["eval_episodes"] == 3  # the evaluator's own count: it played them
        rates = [first[f"eval_{k}_rate"] for k in ("success", "collision", "timeout")]
        assert all(0.0 <= r <= 1.0 for r in rates) and sum(rates) == pytest.approx(1.0)
        assert [e["wall_s"] for e in run_stats.eval_history] == [1.0]

        # A call still in flight at the end is waited for, and its window stands: no extra
        # final episodes are played.
        in_flight = schedule.start()
        schedule.final(in_flight, logger, wall_s=2.0)
        assert run_stats.eval["eval_final_episodes"] == 0
        assert run_stats.eval["eval_episodes"] == 4
        assert len(run_stats.eval_history) == 2
    assert ray.is_initialized()


def test_a_best_policy_that_cannot_be_written_ends_the_run_and_keeps_the_last_record(
    tmp_path: Path,
) -> None:
    """The selector's write fails (here its directory is a file; a full disk fails the same
    way): the schedule keeps the error for the loop to end the run on, and the selection record
    still names no file that was not written."""
    from robogym_ray.errors import DiskWriteError

    with _program(tmp_path, run_name="best", select_episodes=2) as (_, program, logger):
        blocker = tmp_path / "not-a-directory"
        blocker.write_text("")
        program.selector.path = blocker / "policy-best.pt"
        schedule = EvalSchedule(program, RunStats())
        schedule.final(schedule.start(), logger, wall_s=1.0)
        assert isinstance(schedule.failure, DiskWriteError)
        assert str(schedule.failure).startswith(f"cannot write policy file {blocker}/")
        assert program.selector.record == {} and program.selector.best is None
        assert blocker.read_text() == ""


def test_the_final_evaluation_needs_at_least_one_episode() -> None:
    from robogym_ray.errors import ConfigError

    with pytest.raises(ConfigError, match="final_eval_episodes"):
        TrainConfig(task=NAV, final_eval_episodes=0)


def test_a_replacement_evaluator_no_node_can_place_does_not_hold_up_the_end(
    tmp_path: Path,
) -> None:
    short = {"worker_deadline_s": 3.0, "final_eval_episodes": 2}
    with _program(tmp_path, run_name="unplaced", **short) as (cfg, program, logger):
        run_stats = RunStats()
        schedule = EvalSchedule(program, run_stats)
        schedule.final(None, logger, wall_s=1.0)  # one evaluation, then the evaluator is lost
        assert run_stats.eval["eval_episodes"] == cfg.final_eval_episodes
        # Its node is gone, and with it the only node that had the resource it asks for.
        program.cfg = dataclasses.replace(cfg, evaluator_resource="lost-node")
        os.kill(ray.get(program.evaluator.ping.remote()), signal.SIGKILL)
        schedule._take(schedule.start(), logger, wall_s=2.0)  # fails: replaced, not placed
        assert run_stats.evaluator_failures == 1 and program.evaluator is not None
        started = time.monotonic()
        schedule.final(schedule.start(), logger, wall_s=3.0)
        # Given up after worker_deadline_s, not waited on for ever (the margin is for a slow
        # machine's calls around it); the run's rates are the lost evaluator's.
        assert cfg.worker_deadline_s <= time.monotonic() - started < cfg.worker_deadline_s + 60
        assert program.evaluator is None
        assert run_stats.eval["eval_episodes"] == cfg.final_eval_episodes
