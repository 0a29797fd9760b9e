"""robo-gym 2.0.1's own, unmodified client stack against our servers (the acceptance, spec a.1).

robo-gym 2.0.1 + robo-gym-server-modules 0.3.0.1 + protobuf 3.20.3 run in a separate venv
(``robo_gym_venv``); our robot servers and manager run as ``robogym-ray`` subprocesses. Expected
values below are written from the spec, not from our code, so a drift on either side shows.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from tests.compat.harness import Started, run_robo_gym

pytestmark = pytest.mark.slow

# --- spec c.2.1: exact key sets per rs_mode -----------------------------------------------------
_POSE = ("translation_x", "translation_y", "translation_z",
         "rotation_x", "rotation_y", "rotation_z", "rotation_w")  # fmt: skip
_JOINTS = ("base", "shoulder", "elbow", "wrist_1", "wrist_2", "wrist_3")
ROBOT_KEYS = frozenset(
    [f"{j}_joint_position" for j in _JOINTS]
    + [f"{j}_joint_velocity" for j in _JOINTS]
    + [f"ee_to_ref_{p}" for p in _POSE]
    + ["in_collision"]
)
OBJECT_0_KEYS = frozenset(f"object_0_to_ref_{p}" for p in _POSE)
FOREARM_KEYS = frozenset(f"forearm_to_ref_{p}" for p in _POSE)
KEYS = {
    "only_robot": ROBOT_KEYS,
    "1object": ROBOT_KEYS | OBJECT_0_KEYS,
    "1moving2points": ROBOT_KEYS | OBJECT_0_KEYS | FOREARM_KEYS,
}
ROS_ORDER = ("elbow", "shoulder", "base", "wrist_1", "wrist_2", "wrist_3")  # spec c.2.2

F32 = 1e-5  # everything travels as float32


def close(a: float, b: float, tol: float = F32) -> bool:
    return abs(a - b) <= tol * max(1.0, abs(b))


# --- robot servers driven by robo_gym_server_modules.robot_server.client.Client -------------


def test_mir100_server_with_robo_gym_client(
    robo_gym_python: Path, serve: Callable[..., Started]
) -> None:
    server = serve("mir100")  # default scene lab_6x8, as ObstacleAvoidance uses
    out = run_robo_gym(robo_gym_python, "robot_server_calls.py", server.address, "mir100")

    # c.1: 1030 floats everywhere, also before any SetState (the reference manager's probe).
    for name in ("initial", "after_set", "after_actions"):
        assert len(out[name]) == 1030, name
    assert out["get_state_msg"]["success"] and len(out["get_state_msg"]["state"]) == 1030
    sag = out["send_action_get_state"]
    assert sag["success"] and len(sag["state"]) == 1030
    assert out["set_state"] is True and out["send_action"] == [True] * 3

    request, state = out["request"], out["after_set"]
    assert all(close(state[i], request[i]) for i in range(0, 3)), state[0:3]  # target echo
    assert all(close(state[i], request[i]) for i in range(3, 6)), state[3:6]  # teleported pose
    assert state[6] == 0.0 and state[7] == 0.0  # zero twist after a teleport
    assert state[1021:1030] == [0.0] * 9  # obstacle slots are write-only
    assert state[1020] == 0.0  # no collision in the free start pose
    for s in (state, out["after_actions"], sag["state"]):
        lasers = s[8:1020]
        assert all(math.isfinite(r) and 0.05 - F32 <= r <= 29.0 + F32 for r in lasers)
        assert abs(s[6]) <= 1.1 and abs(s[7]) <= 1.6  # NoObstacle's observation bounds

    # Three 0.5 m/s actions along +x (yaw 0): forward motion, about v x 0.1 s per cycle, no turn.
    moved = out["after_actions"]
    dx = moved[3] - request[3]
    assert 0.01 < dx < 0.2, dx
    assert abs(moved[4] - request[4]) < 0.01 and abs(moved[5]) < 0.05
    assert 0.0 < moved[6] <= 0.5 + F32
    assert sag["state"][7] > 0.0  # the 0.7 rad/s turn of SendActionGetState is applied


@pytest.mark.parametrize("rs_mode", ["only_robot", "1object", "1moving2points"])
def test_ur10_server_with_robo_gym_client(
    robo_gym_python: Path, serve: Callable[..., Started], rs_mode: str
) -> None:
    server = serve("ur10", f"rs_mode={rs_mode}", "reference_frame=base_link")
    out = run_robo_gym(robo_gym_python, "robot_server_calls.py", server.address, "ur")
    keys = KEYS[rs_mode]

    for name in ("initial", "after_set", "after_action", "send_action_get_state"):
        msg = out[name]
        assert msg["success"], name
        assert set(msg["state_dict"]) == keys and len(msg["state_dict"]) == len(keys), (
            name,
            sorted(set(msg["state_dict"]) ^ keys),
        )
        assert len(msg["state"]) == len(keys), (name, len(msg["state"]))  # c.2.1 flat list
    assert out["set_state"] is True and out["send_action"] is True

    after = out["after_set"]["state_dict"]
    goal = dict(zip(_JOINTS, (0.0, -2.5, 1.5, -1.5, -1.4, 0.0), strict=True))
    for joint, q in goal.items():  # c.2.3: returns with every joint within 0.03 rad
        assert abs(after[f"{joint}_joint_position"] - q) <= 0.03, joint
    assert after["in_collision"] == 0.0
    # e.2 golden FK: ur10 tool0 in base_link at EndEffectorPositioning's reset pose.
    ee = [after[f"ee_to_ref_translation_{a}"] for a in "xyz"]
    assert all(abs(a - b) < 2e-3 for a, b in zip(ee, (-0.0391, 0.1796, 1.0135), strict=True)), ee
    quat = [after[f"ee_to_ref_rotation_{a}"] for a in "xyzw"]
    assert abs(math.fsum(q * q for q in quat) - 1.0) < 1e-4, quat
    if rs_mode != "only_robot":  # c.2.4 fixed_position, identity rotation
        obj = [after[f"object_0_to_ref_{p}"] for p in _POSE]
        assert all(close(a, b) for a, b in zip(obj, (0.5, 0.3, 0.4, 0, 0, 0, 1), strict=True)), obj
        # Flat order: object_0 (7) first, then positions in ROS order.
        flat = out["after_set"]["state"]
        assert all(close(a, b) for a, b in zip(flat[:7], obj, strict=True))
        positions = flat[7:13]
    else:
        positions = out["after_set"]["state"][0:6]
    ros = [after[f"{j}_joint_position"] for j in ROS_ORDER]
    assert all(close(a, b) for a, b in zip(positions, ros, strict=True)), (positions, ros)

    # c.2.2: the action is in ROS order; its third value is shoulder_pan (+0.2 rad).
    for name in ("after_action", "send_action_get_state"):
        moved = out[name]["state_dict"]
        assert moved["base_joint_position"] > after["base_joint_position"] + 1e-3, name
        assert moved["base_joint_position"] <= 0.2 + 1e-3
        for joint in _JOINTS[1:]:
            assert abs(moved[f"{joint}_joint_position"] - goal[joint]) < 0.03, (name, joint)


# --- robo-gym's envs through our manager (spec b.2, d) --------------------------------------------


def run_env(
    python: Path, manager: Started, mode: str, env_id: str, *flags: str, **kwargs: Any
) -> dict[str, Any]:
    ip, port = manager.address.rsplit(":", 1)
    return run_robo_gym(
        python, "env_episodes.py", mode, env_id, ip, port, "--kwargs", json.dumps(kwargs), *flags
    )


STATUSES = {"success", "collision", "max_steps_exceeded", "out of boundary"}  # spec d


def check_episode(out: dict[str, Any], obs_dim: int, limit: int, manager: Started) -> None:
    """A whole episode ran: observations in the space every step, ended by the env's own rules."""
    assert out["robot_server"].startswith(manager.address.rsplit(":", 1)[0] + ":")  # b.3
    assert out["reset_obs_shape"] == [obs_dim] and out["reset_obs_in_space"]
    steps = out["steps"]
    assert 0 < len(steps) <= limit
    for step in steps:
        assert step["obs_shape"] == [obs_dim] and step["obs_in_space"], step
        assert math.isfinite(step["reward"]) and not step["truncated"], step
    assert steps[-1]["terminated"] and steps[-1]["final_status"] in STATUSES, steps[-1]
    assert all(not s["terminated"] for s in steps[:-1])
    assert out["killed"]


@pytest.mark.parametrize(
    ("env_id", "obs_dim", "limit", "kwargs", "policy"),
    [
        ("NoObstacleNavigationMir100Sim-v0", 4, 500, {}, "goto"),
        ("EndEffectorPositioningURSim-v0", 27, 300, {"ur_model": "ur10"}, "random"),
        ("EmptyEnvironmentURSim-v0", 12, 300, {}, "random"),
    ],
)
def test_robo_gym_env_through_gym_make(
    robo_gym_python: Path,
    manager: Started,
    env_id: str,
    obs_dim: int,
    limit: int,
    kwargs: dict[str, Any],
    policy: str,
) -> None:
    out = run_env(
        robo_gym_python, manager, "gym", env_id, "--policy", policy, "--restart", **kwargs
    )
    check_episode(out, obs_dim, limit, manager)
    assert out["reset_info_keys"] == []
    if policy == "goto":  # the robot went where robo-gym's env believed the target to be (d.1)
        assert out["steps"][-1]["final_status"] == "success", out["steps"][-1]
        assert out["steps"][-1]["reward"] == 200.0
    # restart_sim (robo-gym's error recovery): the old server is gone, a new one serves.
    restart = out["restart"]
    assert restart["old"] == out["robot_server"] and restart["reset_obs_in_space"]
    assert restart["old_gone"] or restart["new"] == restart["old"]  # (a reused port answers)
    assert restart["step"]["obs_in_space"], restart["step"]


def test_obstacle_avoidance_mir100_through_unwrapped(
    robo_gym_python: Path, manager: Started
) -> None:
    # 2.0.1's legacy reset signature only works on env.unwrapped (spec d).
    out = run_env(robo_gym_python, manager, "unwrapped", "ObstacleAvoidanceMir100Sim-v0")
    check_episode(out, 20, 500, manager)


@pytest.mark.parametrize("env_id", ["BasicAvoidanceURSim-v0", "AvoidanceRaad2022URSim-v0"])
def test_ur_avoidance_servers_start(robo_gym_python: Path, manager: Started, env_id: str) -> None:
    # Their reset is broken in 2.0.1 (spec d), but gym.make starts a 1moving2points server,
    # which robo-gym's own client then reads through the env.
    out = run_env(robo_gym_python, manager, "make", env_id)
    assert set(out["state_dict_keys"]) == KEYS["1moving2points"]
    assert out["state_len"] == 34 and out["killed"]
