"""TensorBoard writer plus the terminal progress bar of a training run."""

from __future__ import annotations

import io
import time
from collections.abc import Mapping
from pathlib import Path

from PIL import Image
from tensorboard.compat.proto.summary_pb2 import Summary
from torch.utils.tensorboard import SummaryWriter
from tqdm import tqdm


class RunLogger:
    """Scalars go to ``run_dir`` (one TensorBoard run per experiment); progress to stderr."""

    def __init__(self, run_dir: Path, total: int, progress: bool = True) -> None:
        self.writer = SummaryWriter(log_dir=str(run_dir))
        self.bar = tqdm(total=total, unit="step", disable=not progress, dynamic_ncols=True)
        self._last_write = 0.0

    def scalar(self, tag: str, value: float, step: int) -> None:
        self.writer.add_scalar(tag, value, step)

    def gif(self, tag: str, data: bytes, step: int) -> None:
        """An animated GIF as an image summary: TensorBoard's image tab plays it."""
        width, height = Image.open(io.BytesIO(data)).size
        image = Summary.Image(height=height, width=width, colorspace=3, encoded_image_string=data)
        # add_image would re-encode one frame as PNG; torch's own add_video does this same call.
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
            self.writer.add_scalar(tag, value, step)
        self.bar.set_postfix(
            success=f"{scalars.get('train/success_rate', 0):.2f}",
            ret=f"{scalars.get('train/return_last100', 0):.1f}",
            learner=int(scalars.get("learner/steps", 0)),
        )

    def close(self) -> None:
        self.writer.flush()
        self.writer.close()
        self.bar.close()
