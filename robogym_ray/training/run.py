"""The distributed training program: rollout workers -> learner -> weights -> workers.

``run_training`` is the driver: it joins or starts Ray, builds the run's actors
(``program.Program``: supervisor and robot servers, learner, rollout workers, evaluator, real
robots) and drives them with ``loop.TrainingLoop`` until ``total_steps``. Everything the user
watches goes to TensorBoard under ``STORAGE/RUN_NAME``; the summary to ``summary.json``.
"""

from __future__ import annotations

import json
import os
import signal
import sys
import threading
from collections.abc import Callable, Mapping
from dataclasses import replace
from typing import Any

import ray

from robogym_ray.config import FLAGS, Words
from robogym_ray.robots.emulation import EmulationConfig
from robogym_ray.training import setup
from robogym_ray.training.config import TrainConfig
from robogym_ray.training.loop import TrainingLoop
from robogym_ray.training.presets import d4pg_for, resolve_task
from robogym_ray.training.program import Program


class RunControl:
    """A training driven from outside its loop (a Tune trial): ``on_eval`` gets each evaluator
    window's figures (``TrainingLoop``'s), ``on_progress`` the counts and rates every
    ``progress_every`` env steps between them (0: never), and ``stop(by)``, from any thread,
    ends the run as a signal does - also when asked before the loop exists (while the actors
    start).

    ``checkpointed``: the run's counts before this part (``ending.COUNTS`` and ``parts``) as
    the caller's own checkpoint recorded them (a Tune trial restored from one); the summary's
    ``whole_run`` counts from them when the earlier part wrote no summary (it was killed)."""

    def __init__(
        self,
        on_eval: Callable[[dict[str, float]], None] | None = None,
        checkpointed: Mapping[str, Any] | None = None,
        on_progress: Callable[[dict[str, float]], None] | None = None,
        progress_every: int = 0,
    ) -> None:
        self.on_eval = on_eval
        self.progress = (progress_every, on_progress) if on_progress and progress_every else None
        self.checkpointed = checkpointed
        self._lock = threading.Lock()
        self._loop: TrainingLoop | None = None
        self._asked: str | None = None

    def stop(self, by: str) -> None:
        with self._lock:
            self._asked = self._asked or by
            if self._loop is not None:
                self._loop.request_stop(by)

    def attach(self, loop: TrainingLoop) -> None:
        with self._lock:
            self._loop = loop
            if self._asked is not None:
                loop.request_stop(self._asked)


def run_training(
    cfg: TrainConfig,
    d4pg_overrides: Mapping[str, Any] | None = None,
    emulation: EmulationConfig | None = None,
    control: RunControl | None = None,
    words: Words = FLAGS,
) -> dict:
    """Run one training to completion; returns the summary (also in ``summary.json``).

    ``emulation`` is what the ``cfg.emulated_workers`` workers' robots differ by (default
    ``EmulationConfig()``, the emulated robot ``robogym-ray serve --emulate-hardware`` serves).
    ``control``: a caller's hooks into the running loop (a Tune trial's). ``words``: how the
    checks made once Ray is joined (the run's name, the cluster's CPUs) name the settings.
    """
    preset = resolve_task(cfg.task)
    d4pg = d4pg_for(preset, d4pg_overrides, cfg)
    place = setup.run_place(cfg, preset.env_id, words)
    cfg = replace(cfg, run_name=place.name)  # config.json records the name
    started_ray = setup.ensure_ray(cfg.address, cfg.num_cpus)
    try:
        program = Program(cfg, d4pg, preset, emulation or EmulationConfig(), place, words)
    except BaseException:
        if started_ray:
            ray.shutdown()
        raise
    loop = TrainingLoop(
        program,
        on_eval=control.on_eval if control else None,
        checkpointed=control.checkpointed if control else None,
        progress=control.progress if control else None,
    )
    if control is not None:
        control.attach(loop)
    previous = _stop_on_signals(loop)
    try:
        record = json.dumps(program.config_record(), indent=2).encode()
        program.storage.write_bytes("config.json", record, "run config")  # DiskWriteError
        return loop.run()
    finally:
        for signum, handler in previous.items():
            signal.signal(signum, handler)
        program.shutdown()
        if started_ray:
            ray.shutdown()


def _stop_on_signals(loop: TrainingLoop) -> dict[int, Any]:
    """SIGINT (Ctrl-C) and SIGTERM (``ray job stop``, a batch system's time limit) end the run
    the way total_steps does, recorded as ``stopped``: collection stops, the final checkpoint
    and summary.json are written. A second signal exits at once (status 130 or 143), as a user
    pressing Ctrl-C again expects. Returns the handlers replaced (none when this is not the main
    thread, where Python allows no handler)."""
    if threading.current_thread() is not threading.main_thread():
        return {}

    def stop(signum: int, frame: Any) -> None:
        name = signal.Signals(signum).name
        if loop.stop.is_set() and loop.stopped_by is not None:
            print(f"\n{name} again: exiting now, without the final checkpoint", file=sys.stderr)
            os._exit(128 + signum)  # Ray's threads would keep a normal exit waiting
        loop.request_stop(name)
        print(f"\n{name}: stopping - writing the final checkpoint and summary "
              f"({name} again to exit at once)", file=sys.stderr, flush=True)  # fmt: skip

    return {s: signal.signal(s, stop) for s in (signal.SIGINT, signal.SIGTERM)}
