"""Where a policy's final rotation error lies on IsaacReachUR10Sim-v0: 100 greedy episodes
(seeds 1000-1099, those of ``robogym-ray evaluate``), each with the command's yaw (commands are
Rz(yaw) Ry(pi/2)), the error's rotation vector in the command's frame (``err_cmd_frame``, rad)
and the final joints (rad).

    python docs/results/isaac-reach-ur10-rotation-by-yaw-2026-11-28/rotation_by_yaw.py \
        RUN/checkpoints/learner.pt OUT.json

A record of the 2026-11-28 measurement in results-log.md, not a tool of the package.
"""

import json
import sys
from collections import Counter

import gymnasium as gym
import numpy as np
from scipy.spatial.transform import Rotation

import robogym_ray.envs  # noqa: F401 - registers the ids
from robogym_ray.envs.frames import frame_rotation
from robogym_ray.experience.episodes import greedy_episode
from robogym_ray.export import load_policy

path, out = sys.argv[1], sys.argv[2]
policy = load_policy(path, False)  # the checkpoint's average, as evaluate scores it
env = gym.make("RoboGymRay/IsaacReachUR10Sim-v0")
task = env.unwrapped
rows = []
for i in range(100):
    ep = greedy_episode(env, policy, 1000 + i)
    cmd = Rotation.from_quat(task.target_pose[3:])
    here = frame_rotation(task._last_msg.state_dict, "ee")
    m = cmd.as_matrix()
    rows.append(
        {
            "seed": 1000 + i,
            "status": ep.final_status,
            "pos": ep.position_error,  # m
            "rot": ep.rotation_error,  # rad
            "err_cmd_frame": (cmd.inv() * here).as_rotvec().tolist(),
            "yaw": float(np.arctan2(-m[0, 1], m[1, 1])),
            "quat": task.target_pose[3:].tolist(),  # the command, x-y-z-w
            "ee_quat": here.as_quat().tolist(),
            "joints": np.asarray(task.joints(task._last_msg)).tolist(),
        }
    )
with open(out, "w") as f:
    json.dump(rows, f, indent=1)
rot = np.array([r["rot"] for r in rows])
yaw = np.abs([r["yaw"] for r in rows])
axes = np.abs([r["err_cmd_frame"] for r in rows])
print(f"median rotation error {np.median(rot):.3f} rad; per axis", np.median(axes, 0).round(3))
for lo, hi in [(0, 1), (1, 2), (2, 2.6), (2.6, 3.2)]:
    sel = (yaw >= lo) & (yaw < hi)
    won = np.mean([rows[k]["status"] == "success" for k in np.flatnonzero(sel)])
    median = np.median(rot[sel])
    print(
        f"|yaw| in [{lo}, {hi}): {sel.sum()} episodes, median {median:.3f} rad, {won:.0%} success"
    )
print(Counter(r["status"] for r in rows))
print(f"corr(|yaw|, rotation error) {np.corrcoef(yaw, rot)[0, 1]:.2f}")
