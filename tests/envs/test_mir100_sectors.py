"""ObstacleAvoidanceSectors: the same task as ObstacleAvoidance, nearest range per laser sector."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import robogym_ray  # noqa: F401 - registers the ids
from robogym_ray.envs.mir100_sectors import SECTOR_STARTS
from robogym_ray.envs.mir100_tasks import LASER, LASER_OFFSETS
from robogym_ray.errors import InvalidStateError
from robogym_ray.protocol import robot_server_pb2 as pb

BEAMS = "RoboGymRay/ObstacleAvoidanceMir100Sim-v0"
SECTORS = "RoboGymRay/ObstacleAvoidanceSectorsMir100Sim-v0"
SECTOR_ENDS = np.append(SECTOR_STARTS[1:], LASER.stop - LASER.start)


def test_sectors_partition_the_scan_around_robo_gyms_beams():
    assert SECTOR_STARTS[0] == 0 and np.all(SECTOR_ENDS > SECTOR_STARTS)
    assert np.all(SECTOR_STARTS <= LASER_OFFSETS) and np.all(LASER_OFFSETS < SECTOR_ENDS)
    # Each sector reaches about halfway to its neighbours' beams: 34 at the two scan ends.
    assert set(np.diff(np.append(SECTOR_STARTS, 1012))) <= {34, 67, 68}


def test_same_task_nearest_range_per_sector():
    """Same seed and actions: same scene, rewards and ends; lasers are the per-sector minima."""
    beams, sectors = gym.make(BEAMS).unwrapped, gym.make(SECTORS).unwrapped
    actions = np.random.default_rng(3).uniform(-1, 1, (40, 2)).astype(np.float32)
    strictly_nearer = 0
    try:
        for seed in (0, 1):
            obs_b, _ = beams.reset(seed=seed)
            obs_s, _ = sectors.reset(seed=seed)
            np.testing.assert_array_equal(beams.obstacles, sectors.obstacles)
            for action in actions:
                raw = np.asarray(sectors.client.get_state().state[LASER], np.float32)
                expected = [raw[a:b].min() for a, b in zip(SECTOR_STARTS, SECTOR_ENDS, strict=True)]
                np.testing.assert_array_equal(obs_s[4:], expected)
                np.testing.assert_array_equal(obs_s[:4], obs_b[:4])
                assert np.all(obs_s[4:] <= obs_b[4:])
                strictly_nearer += int(np.sum(obs_s[4:] < obs_b[4:] - 0.05))
                obs_b, r_b, term_b, trunc_b, info_b = beams.step(action)
                obs_s, r_s, term_s, trunc_s, info_s = sectors.step(action)
                assert (r_s, term_s, trunc_s) == (r_b, term_b, trunc_b)
                assert info_s.get("final_status") == info_b.get("final_status")
                if term_b or trunc_b:
                    break
    finally:
        beams.close()
        sectors.close()
    # The lab's walls and cubes are not flat around every beam: the minima must see nearer
    # returns than the single beams, or this variant observes nothing new.
    assert strictly_nearer > 20


def test_nan_between_robo_gyms_beams_is_refused():
    """A NaN range that no robo-gym beam samples still reaches the sector observation."""
    env = gym.make(SECTORS).unwrapped
    try:
        env.reset(seed=0)
        state = list(env.client.get_state().state)
        hidden = LASER.start + int(LASER_OFFSETS[3]) + 5  # not one of the 16 sampled beams
        state[hidden] = float("nan")
        with pytest.raises(InvalidStateError, match="nan"):
            env.observe(pb.State(state=state, success=True))
    finally:
        env.close()


def test_short_name_trains_it_like_navigation():
    from robogym_ray.training.presets import d4pg_for, resolve_task

    preset = resolve_task("navigation-sectors")
    assert preset.env_id == SECTORS and gym.spec(SECTORS) is not None
    assert d4pg_for(preset) == d4pg_for(resolve_task("navigation"))
    assert gym.spec(SECTORS.replace("Sim-v0", "Rob-v0")).kwargs == {"real_robot": True}
