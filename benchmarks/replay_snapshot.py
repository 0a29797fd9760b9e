"""What a replay snapshot costs: size on disk and time to write and read back, at 1 M
transitions of the navigation task (20-float observations, 2-float actions).

    python benchmarks/replay_snapshot.py [--transitions 1000000] [--obs-dim 20] [--act-dim 2]

A learner that Ray restarts restores its latest checkpoint; with replay snapshots
(``--replay-snapshot-every``) the checkpoint carries the replay too, and the restarted learner
loses only what was inserted since. This times ``D4PGLearner.save(include_replay=True)`` and
``restore`` on a full replay (the networks are the paper's (400, 300)).
"""

from __future__ import annotations

import argparse
import datetime
import os
import platform
import tempfile
import time
from pathlib import Path

import numpy as np

from robogym_ray.learner.checkpoint import replay_path
from robogym_ray.learner.config import D4PGConfig
from robogym_ray.learner.learner import D4PGLearner


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--transitions", type=int, default=1_000_000)
    parser.add_argument("--obs-dim", type=int, default=20)
    parser.add_argument("--act-dim", type=int, default=2)
    args = parser.parse_args()
    n = args.transitions
    cfg = D4PGConfig(replay_capacity=n, min_replay_size=1)
    learner = D4PGLearner(cfg, args.obs_dim, args.act_dim)
    rng = np.random.default_rng(0)
    chunk = 50_000
    for start in range(0, n, chunk):
        m = min(chunk, n - start)
        learner.add({
            "obs": rng.normal(size=(m, args.obs_dim)).astype(np.float32),
            "action": rng.uniform(-1, 1, size=(m, args.act_dim)).astype(np.float32),
            "reward": rng.normal(size=m).astype(np.float32),
            "discount": np.full(m, 0.95, np.float32),
            "next_obs": rng.normal(size=(m, args.obs_dim)).astype(np.float32),
        })  # fmt: skip
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "learner.pt"
        start = time.perf_counter()
        learner.save(path, include_replay=True)
        write_s = time.perf_counter() - start
        size = path.stat().st_size + replay_path(path).stat().st_size
        clone = D4PGLearner(cfg, args.obs_dim, args.act_dim)
        start = time.perf_counter()
        clone.restore(path)
        read_s = time.perf_counter() - start
        assert len(clone.replay) == n
    print(
        f"{datetime.date.today()}, {platform.node()}, {os.cpu_count()} CPUs: {n:,} transitions "
        f"(obs {args.obs_dim}, act {args.act_dim}): {size / 1e6:,.0f} MB, "
        f"write {write_s:.2f} s, read {read_s:.2f} s"
    )


if __name__ == "__main__":
    main()
