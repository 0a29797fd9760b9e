"""Runs in the robo-gym venv: robo-gym 2.0.1's own envs against a server manager (spec b, d).

    python env_episodes.py MODE ENV_ID IP PORT [--kwargs JSON] [--steps N] [--policy P]
        [--restart] --out FILE

MODE ``gym``: ``gym.make`` (which starts the robot server, b.2), reset(seed=0), steps until the
episode ends (random actions, or ``--policy goto``: MiR heads for its target) [, ``restart_sim()``
+ reset + step], close.
MODE ``unwrapped``: for 2.0.1's legacy-signature envs (ObstacleAvoidanceMir100, spec d): reset and
step ``env.unwrapped``. MODE ``make``: for envs whose reset is broken in 2.0.1 (the UR avoidance
envs): only ``gym.make``, then one GetState through the env's own robot-server client.
The manager is found by scanning ``range(PORT, PORT + 1)``. The server is always killed at the end
through the env's own ``kill_sim`` (UR ``close()`` does not kill, spec b.6; MiR's already did, and
``kill_sim`` then sends nothing).
"""

from __future__ import annotations

import argparse
import json

import grpc
import gymnasium as gym
import numpy as np
import robo_gym  # noqa: F401 - registers the env ids


def record_step(env_space: gym.Space, result: tuple) -> dict:
    obs, reward, terminated, truncated, info = result
    return {
        "obs_shape": list(np.shape(obs)),
        "obs_in_space": bool(env_space.contains(obs)),
        "reward": float(reward),
        "terminated": bool(terminated),
        "truncated": bool(truncated),
        "info_keys": sorted(k for k in info if k != "rs_state"),
        "final_status": info.get("final_status"),
    }


def restart(env: gym.Env, sim: gym.Env) -> dict:
    """What robo-gym's ExceptionHandling wrapper does after an error: a fresh robot server."""
    old_client, old_address = sim.client, sim.robot_server_ip
    sim.restart_sim()
    try:
        old_client.get_state_msg()
        old_gone = False
    except grpc.RpcError:
        old_gone = True
    obs, _ = env.reset(seed=1)
    step = record_step(sim.observation_space, env.step(env.action_space.sample()))
    return {
        "old": old_address,
        "new": sim.robot_server_ip,
        "old_gone": old_gone,
        "reset_obs_in_space": bool(sim.observation_space.contains(obs)),
        "step": step,
    }


def go_to_target(obs: np.ndarray) -> np.ndarray:
    """MiR: turn toward the target (obs[1] = bearing), drive when roughly facing it."""
    bearing = float(obs[1])
    return np.array([1.0 if abs(bearing) < 0.5 else 0.0, np.clip(3.0 * bearing, -1, 1)], "f4")


def episode(env: gym.Env, sim: gym.Env, mode: str, steps: int, policy: str) -> dict:
    """Reset, then step until terminated or ``steps`` steps; what the env returned."""
    env.action_space.seed(0)
    out: dict = {"steps": []}
    if mode == "gym":
        obs, info = env.reset(seed=0)
        out["reset_info_keys"] = sorted(info)
    else:  # legacy signature: no seed, bare observation
        sim.seed(0)
        np.random.seed(0)  # ObstacleAvoidance draws the start side from the global RNG
        obs = sim.reset()
    out["reset_obs_shape"] = list(np.shape(obs))
    out["reset_obs_in_space"] = bool(sim.observation_space.contains(obs))
    stepper = env if mode == "gym" else sim
    for _ in range(steps):
        action = go_to_target(obs) if policy == "goto" else env.action_space.sample()
        result = stepper.step(action)
        obs = result[0]
        out["steps"].append(record_step(sim.observation_space, result))
        if out["steps"][-1]["terminated"]:
            break
    return out


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("mode", choices=["gym", "unwrapped", "make"])
    parser.add_argument("env_id")
    parser.add_argument("ip")
    parser.add_argument("port", type=int)
    parser.add_argument("--kwargs", default="{}", help="extra gym.make kwargs as JSON")
    parser.add_argument("--steps", type=int, default=600, help="at most; stops when terminated")
    parser.add_argument("--policy", choices=["random", "goto"], default="random")
    parser.add_argument(
        "--restart", action="store_true", help="then restart_sim() (KillServer + StartNewServer)"
    )
    parser.add_argument("--out", required=True)
    args = parser.parse_args()

    bounds = {"lower_bound_port": args.port, "upper_bound_port": args.port + 1}
    env = gym.make(args.env_id, ip=args.ip, **bounds, **json.loads(args.kwargs))
    sim = env.unwrapped
    out: dict = {"robot_server": sim.robot_server_ip}
    if args.mode == "make":
        msg = sim.client.get_state_msg()
        out["state_dict_keys"] = sorted(msg.state_dict)
        out["state_len"] = len(msg.state)
    else:
        out.update(episode(env, sim, args.mode, args.steps, args.policy))
        if args.restart:
            out["restart"] = restart(env, sim)
        env.close()
    sim.kill_sim()
    out["killed"] = not sim.expect_sim_running
    with open(args.out, "w") as f:
        json.dump(out, f)


if __name__ == "__main__":
    main()
