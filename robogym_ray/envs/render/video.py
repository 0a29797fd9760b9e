"""Episode videos: MP4 files (``evaluate --video``) and animated GIFs for TensorBoard.

MP4s are encoded by ``imageio-ffmpeg`` (the ``video`` extra), whose wheel carries its ffmpeg
binary, so nothing is downloaded at run time. TensorBoard's own video path needs moviepy 1.x;
an animated GIF in an image summary is what it displays, made here with Pillow.
"""

from __future__ import annotations

import io
import re
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from PIL import Image

from robogym_ray.errors import ConfigError, RenderError


def write_mp4(path: str | Path, frames: Sequence[np.ndarray], fps: float) -> Path:
    """Encode ``frames`` (uint8 H x W x 3, all one size) as an H.264 MP4 at ``fps``."""
    try:
        import imageio_ffmpeg
    except ImportError as exc:  # pragma: no cover - the video extra installs it
        raise RenderError("videos need imageio-ffmpeg: pip install 'robogym-ray[video]'") from exc
    if not frames:
        raise ConfigError(f"{path}: no frames to write")
    height, width = frames[0].shape[:2]
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    # yuv420p needs even sides (macro_block_size=2: odd sizes are padded by one pixel).
    writer = imageio_ffmpeg.write_frames(
        str(path), (width, height), fps=fps, pix_fmt_out="yuv420p", macro_block_size=2
    )
    writer.send(None)
    for frame in frames:
        writer.send(np.ascontiguousarray(frame, dtype=np.uint8))
    writer.close()
    return path


def gif_bytes(frames: Sequence[np.ndarray], fps: float) -> bytes:
    """An animated GIF of ``frames`` (looping), as bytes."""
    images = [Image.fromarray(np.asarray(f, dtype=np.uint8)) for f in frames]
    buffer = io.BytesIO()
    images[0].save(
        buffer, format="GIF", save_all=True, append_images=images[1:],
        duration=max(20, int(1000 / fps)), loop=0,
    )  # fmt: skip
    return buffer.getvalue()


class EpisodeVideos:
    """Which episodes of an evaluation are filmed, and where their MP4s go.

    Args:
        directory: where the files go (made if missing).
        episodes: film the first this many episodes.
        fps: frame rate of the files (the env's ``render_fps``).
    """

    def __init__(self, directory: str | Path, episodes: int, fps: float) -> None:
        if episodes < 1:
            raise ConfigError(f"video episodes must be >= 1, got {episodes}")
        self.directory, self.episodes, self.fps = Path(directory), episodes, fps
        self.written: list[Path] = []

    def wants(self, index: int) -> bool:
        return index < self.episodes

    def save(self, index: int, seed: int, status: str, frames: Sequence[np.ndarray]) -> Path:
        """``episode-INDEX-seed-SEED-STATUS.mp4``."""
        safe = re.sub(r"[^A-Za-z0-9_]+", "_", status)
        name = f"episode-{index:03d}-seed-{seed}-{safe}.mp4"
        path = write_mp4(self.directory / name, frames, self.fps)
        self.written.append(path)
        return path
