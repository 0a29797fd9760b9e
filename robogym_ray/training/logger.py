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


class RunLogger:
    """Scalars go to ``run_dir`` (one TensorBoard run per experiment); progress to stderr.

    A TensorBoard write that fails (a full disk) does not raise: TensorBoard stops for this
    run, ``error`` keeps the first failure and ``stop`` (when given) is set, so the training
    loop ends the run and reports it in one line rather than a traceback.
    """

    def __init__(
        self,
        run_dir: Path,
        total: int,
        progress: bool = True,
        stop: threading.Event | None = None,
        storage: RunStorage | None = None,
    ) -> None:
        """``storage``: an object store the events are uploaded to from ``run_dir`` (a local
        staging folder) at every ``write`` and at ``close``; None: ``run_dir`` is their home."""
        self.run_dir = run_dir
        self.storage = storage
        self.error: DiskWriteError | None = None
        self._stop = stop
        self.writer: SummaryWriter | None = None
        _quiet_tensorboard_threads()
        with self._guarded():
            self.writer = SummaryWriter(log_dir=str(run_dir))
        self.bar = tqdm(total=total, unit="step", disable=not progress, dynamic_ncols=True)
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
