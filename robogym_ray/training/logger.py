"""TensorBoard writer plus the terminal progress bar of a training run."""

from __future__ import annotations

import io
import threading
import time
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from PIL import Image
from tensorboard.compat.proto.summary_pb2 import Summary
from torch.utils.tensorboard import SummaryWriter
from tqdm import tqdm

from robogym_ray.errors import DiskWriteError
from robogym_ray.storage import RunStorage


def eta_s(
    done: int,
    total: int | None,
    elapsed_s: float,
    rate: float | None,
    max_wall_s: float | None = None,
) -> float | None:
    """Seconds until the run ends: at ``rate`` steps/s the step total's time (none without a
    total: a run given only --max-wall-s), or the wall limit's (``max_wall_s``), whichever comes
    first; None while neither is known. Never negative: steps in flight when the total is
    reached land past it."""
    by_steps = max(0, total - done) / rate if rate and total is not None else None
    if max_wall_s is None:
        return by_steps
    by_wall = max(0.0, max_wall_s - elapsed_s)
    return by_wall if by_steps is None else min(by_steps, by_wall)


class ProgressBar(tqdm):
    """tqdm's bar whose time left is ``eta_s``'s: a run about to reach --max-wall-s says so,
    not the hour its step total would take. Steps past the total (those in flight when it was
    reached) keep the total shown and the bar full; tqdm's own would show ``3016/?`` and a
    negative time left."""

    def __init__(self, *args: Any, max_wall_s: float | None = None, **kwargs: Any) -> None:
        self.max_wall_s = max_wall_s
        bar = "{l_bar}{bar}| {n_fmt}/{goal} [{elapsed}<{left}, {rate_fmt}{postfix}]"
        super().__init__(*args, bar_format=bar, **kwargs)

    @property
    def format_dict(self) -> dict[str, Any]:
        d = super().format_dict
        elapsed = d.get("elapsed") or 0.0
        rate = d.get("rate")
        if rate is None and elapsed:  # as tqdm's own format_meter falls back
            rate = (d["n"] - (d.get("initial") or 0)) / elapsed
        total = d["total"]
        left = eta_s(d["n"], total, elapsed, rate, self.max_wall_s)
        return {
            **d,
            "total": None if total is None else max(total, d["n"]),
            "goal": "?" if total is None else str(total),
            "left": "?" if left is None else self.format_interval(left),
        }


class RunLogger:
    """Scalars go to ``run_dir`` (one TensorBoard run per experiment); progress to stderr.

    A TensorBoard write that fails (a full disk) does not raise: TensorBoard stops for this
    run, ``error`` keeps the first failure and ``stop`` (when given) is set, so the training
    loop ends the run and reports it in one line rather than a traceback.
    """

    def __init__(
        self,
        run_dir: Path,
        total: int | None,
        progress: bool = True,
        stop: threading.Event | None = None,
        storage: RunStorage | None = None,
        max_wall_s: float | None = None,
    ) -> None:
        """``storage``: an object store the events are uploaded to from ``run_dir`` (a local
        staging folder) at every ``write`` and at ``close``; None: ``run_dir`` is their home.
        ``total``: the run's step total (None: no step cap, a run given only a wall limit).
        ``max_wall_s``: the run's wall limit, which the progress bar's time left respects."""
        self.run_dir = run_dir
        self.storage = storage
        self.error: DiskWriteError | None = None
        self._stop = stop
        self.writer: SummaryWriter | None = None
        _quiet_tensorboard_threads()
        with self._guarded():
            self.writer = SummaryWriter(log_dir=str(run_dir))
        self.bar = ProgressBar(total=total, unit="step", disable=not progress, dynamic_ncols=True,
                               max_wall_s=max_wall_s)  # fmt: skip
        self._last_write = 0.0

    @contextmanager
    def _guarded(self) -> Iterator[None]:
        try:
            yield
        except OSError as exc:
            if self.error is None:
                self.error = DiskWriteError.of("TensorBoard events in", self.run_dir, exc)
            # Not closed: its close flushes, and fails, again. Its thread has ended already.
            self.writer = None
            if self._stop is not None:
                self._stop.set()

    def scalar(self, tag: str, value: float, step: int) -> None:
        if self.writer is not None:
            with self._guarded():
                self.writer.add_scalar(tag, value, step)

    def gif(self, tag: str, data: bytes, step: int) -> None:
        """An animated GIF as an image summary: TensorBoard's image tab plays it."""
        width, height = Image.open(io.BytesIO(data)).size
        image = Summary.Image(height=height, width=width, colorspace=3, encoded_image_string=data)
        if self.writer is not None:
            with self._guarded():
                # add_image would re-encode one frame as PNG; torch's add_video does this call.
                self.writer._get_file_writer().add_summary(
                    Summary(value=[Summary.Value(tag=tag, image=image)]), step
                )

    def advance(self, steps: int) -> None:
        self.bar.update(steps)

    def due(self, every_s: float) -> bool:
        """Whether ``every_s`` seconds have passed since the last write."""
        return time.monotonic() - self._last_write >= every_s

    def write(self, scalars: Mapping[str, float], step: int) -> None:
        self._last_write = time.monotonic()
        for tag, value in scalars.items():
            self.scalar(tag, value, step)
        self.bar.set_postfix(
            success=f"{scalars.get('train/success_rate', 0):.2f}",
            ret=f"{scalars.get('train/return_last100', 0):.1f}",
            learner=int(scalars.get("learner/steps", 0)),
        )
        self._upload()

    def _upload(self) -> None:
        """The event files, whole, to an object store (they are small: scalars and GIFs)."""
        if self.storage is None or self.writer is None:
            return
        with self._guarded():
            self.writer.flush()
            for events in self.run_dir.glob("events.out.tfevents.*"):
                try:
                    self.storage.upload(events, events.name, "TensorBoard events")
                except DiskWriteError as exc:
                    raise OSError(str(exc)) from None

    def close(self) -> None:
        self._upload()
        if self.writer is not None:
            with self._guarded():
                self.writer.flush()
                self.writer.close()
        self.bar.close()


_quieted = False


def _quiet_tensorboard_threads() -> None:
    """TensorBoard's writer thread keeps a write error (a full disk) for the writer's next call,
    where ``RunLogger`` handles it, and also raises it, which Python prints as an "Exception in
    thread" traceback; that print is left out (only for OSErrors of TensorBoard's threads)."""
    global _quieted
    if _quieted:
        return
    _quieted = True
    previous = threading.excepthook

    def hook(args: Any) -> None:
        module = type(args.thread).__module__ if args.thread is not None else ""
        if not (isinstance(args.exc_value, OSError) and module.startswith("tensorboard.")):
            previous(args)

    threading.excepthook = hook
