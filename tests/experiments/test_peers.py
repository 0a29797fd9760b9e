"""experiments/peers.py: a peer trains on a wall-clock budget and its snapshots are scored by
the same greedy episodes as ``robogym-ray evaluate`` (plumbing, not learning)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from tests.experiments.test_scripts import script

pytest.importorskip("stable_baselines3")


@pytest.mark.parametrize("algo", ["sb3-td3", "sb3-sac"])
def test_a_peer_saves_snapshots_by_wall_time_and_each_is_scored(tmp_path: Path, algo: str) -> None:
    peers = script("peers")
    out = tmp_path / algo
    record = peers.train(algo, "navigation", minutes=0.04, seed=0, out=out, save_every_min=0.02)
    assert [s["wall_min"] for s in record["snapshots"]] == [0.02, 0.04]
    steps = [s["env_steps"] for s in record["snapshots"]]
    assert 0 < steps[0] < steps[1] == record["env_steps"]
    # SB3's off-policy defaults: one gradient update per env step once learning starts (100
    # steps); the budget can end a step after its env step, before its update.
    assert record["env_steps"] - 101 <= record["gradient_updates"] <= record["env_steps"] - 100
    curve = peers.evaluate(out, episodes=2, seed=1000)
    assert json.loads((out / "curve.json").read_text()) == curve
    assert [c["wall_min"] for c in curve] == [0.02, 0.04]
    for point in curve:
        rates = [point[f"{k}_rate"] for k in ("success", "collision", "timeout", "other")]
        assert point["episodes"] == 2 and sum(rates) == pytest.approx(1.0)
