"""The checkpoint layout's reads: a replay file never unpickles, a bad file is a ConfigError."""

from __future__ import annotations

import pickle
from pathlib import Path

import numpy as np
import pytest
import torch

from robogym_ray.errors import ConfigError
from robogym_ray.learner import checkpoint


class _Payload:
    """Unpickling this runs code: what a hostile replay file could carry."""

    ran = False

    def __reduce__(self):
        return (_mark_ran, ())


def _mark_ran() -> None:
    _Payload.ran = True


def test_a_replay_file_with_pickled_data_is_refused_without_running_it(tmp_path: Path) -> None:
    path = tmp_path / "learner.pt.replay.npz"
    with open(path, "wb") as f:
        np.savez(f, counters=np.zeros(3, np.int64), rng_state=np.array(_Payload(), dtype=object))
    with pytest.raises(ConfigError, match="pickled data is not loaded"):
        checkpoint.read_replay(path)
    assert not _Payload.ran
    assert pickle.loads(pickle.dumps(_Payload())) is None and _Payload.ran  # it would have run


def test_the_replay_state_round_trips_without_pickle(tmp_path: Path) -> None:
    rng = np.random.default_rng(3)
    state = {"obs": rng.normal(size=(4, 2)), "rng_state": rng.bit_generator.state}
    path = tmp_path / "r.npz"
    checkpoint.write_replay(path, state)
    with np.load(path, allow_pickle=False) as data:  # plain arrays only
        assert set(data) == {"obs", "rng_state"}
    back = checkpoint.read_replay(path)
    np.testing.assert_array_equal(back["obs"], state["obs"])
    assert back["rng_state"] == state["rng_state"]  # 128-bit PCG64 state, exact


def test_bad_checkpoint_files_are_config_errors(tmp_path: Path) -> None:
    torch.save({"nets": 3}, tmp_path / "a.pt")
    with pytest.raises(ConfigError, match="not a D4PGLearner checkpoint"):
        checkpoint.read(tmp_path / "a.pt")
    with pytest.raises(ConfigError, match="cannot read checkpoint"):
        checkpoint.read(tmp_path / "missing.pt")
    with pytest.raises(ConfigError, match="no nets.policy"):
        checkpoint.policy_weights({"nets": {"critic": {}}})
