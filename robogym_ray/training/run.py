"""The distributed training program: rollout workers -> learner -> weights -> workers.

``run_training`` is the driver: it joins or starts Ray, builds the run's actors
(``program.Program``: supervisor and robot servers, learner, rollout workers, evaluator, real
robots) and drives them with ``loop.TrainingLoop`` until ``total_steps``. Everything the user
watches goes to TensorBoard under ``logdir/run_name``; the summary to ``summary.json``.
"""

from __future__ import annotations

import json
import signal
import threading
from collections.abc import Mapping
from typing import Any

import ray

from robogym_ray.errors import ConfigError
from robogym_ray.learner.checkpoint import write_bytes
from robogym_ray.robots.emulation import EmulationConfig
from robogym_ray.training import setup
from robogym_ray.training.config import TrainConfig
from robogym_ray.training.loop import TrainingLoop
from robogym_ray.training.presets import d4pg_for, resolve_task
from robogym_ray.training.program import Program


def run_training(
    cfg: TrainConfig,
    d4pg_overrides: Mapping[str, Any] | None = None,
    emulation: EmulationConfig | None = None,
) -> dict:
    """Run one training to completion; returns the summary (also in ``run_dir/summary.json``).

    ``emulation`` is what the ``cfg.emulated_workers`` workers' robots differ by (default
    ``EmulationConfig()``, the emulated robot ``robogym-ray serve --emulate-hardware`` serves).
    """
    preset = resolve_task(cfg.task)
    d4pg = d4pg_for(preset, d4pg_overrides)
    if cfg.emulated_workers and not preset.env_id.startswith("RoboGymRay/"):
        raise ConfigError(f"--emulated-workers needs a robot task; {preset.env_id} has none")
    started_ray = setup.ensure_ray(cfg)
    try:
        program = Program(cfg, d4pg, preset, emulation or EmulationConfig())
    except BaseException:
        if started_ray:
            ray.shutdown()
        raise
    loop = TrainingLoop(program)
    previous = _stop_on_sigterm(loop)
    try:
        record = json.dumps(program.config_record(), indent=2).encode()
        write_bytes(program.run_dir / "config.json", record, "run config")  # full: DiskWriteError
        return loop.run()
    finally:
        if previous is not None:
            signal.signal(signal.SIGTERM, previous)
        program.shutdown()
        if started_ray:
            ray.shutdown()


def _stop_on_sigterm(loop: TrainingLoop) -> Any:
    """SIGTERM (e.g. ``ray job stop``, a batch system's time limit) ends the run the way
    total_steps does: the last checkpoint and summary.json are written. Returns the handler it
    replaced (None when this is not the main thread, where Python allows no handler)."""
    if threading.current_thread() is not threading.main_thread():
        return None
    return signal.signal(signal.SIGTERM, lambda signum, frame: loop.stop.set())
