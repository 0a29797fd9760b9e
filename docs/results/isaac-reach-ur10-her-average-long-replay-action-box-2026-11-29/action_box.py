"""The action box of isaac-reach-ur10-her-average-long-replay-box.json, derived, not tuned.

Rule: centred on the default pose (action 0), each joint may move the smallest multiple of
pi/2 rad that holds every final joint offset of the 300 episodes three earlier IsaacReach
policies were scored on (results/isaac-reach-ur10-rotation-by-yaw-2026-11-28/), cut to the
env's own bounds; printed on the [-1, 1] scale of IsaacReachUR10Sim-v0's action Box (joint
offset / 0.5 rad per unit of action), as D4PGConfig.action_box_low / _high take it.

    python docs/results/isaac-reach-ur10-her-average-long-replay-action-box-2026-11-29/action_box.py
"""

import json
from pathlib import Path

import gymnasium as gym
import numpy as np

import robogym_ray.envs  # noqa: F401 - registers the ids
from robogym_ray.envs.ur_modular import IsaacReachUR

SCALE = 0.5  # rad of joint target per unit of action (2.1.0's isaac_scale)
SCORED = Path(__file__).resolve().parents[1] / "isaac-reach-ur10-rotation-by-yaw-2026-11-28"

space = gym.make("RoboGymRay/IsaacReachUR10Sim-v0").action_space
default = np.asarray(IsaacReachUR.default_joints)
joints = np.array(
    [e["joints"] for f in sorted(SCORED.glob("*.json")) for e in json.loads(f.read_text())]
)
reach = np.abs(joints - default).max(axis=0)
travel = np.ceil(reach / (np.pi / 2)) * np.pi / 2
low, high = np.maximum(-travel / SCALE, space.low), np.minimum(travel / SCALE, space.high)
scale = lambda a: 2 * (a - space.low) / (space.high - space.low) - 1  # noqa: E731
print("episodes", len(joints), "largest offsets (rad)", np.round(reach, 3).tolist())
print("travel (rad)", np.round(travel, 4).tolist())
print('"action_box_low":', np.round(scale(low), 4).tolist())
print('"action_box_high":', np.round(scale(high), 4).tolist())
