"""How franky follows a stream of joint targets at a policy's rate, on franky-sim (MuJoCo FR3).

The Franka backend (``robots/panda/franky_arm.py``) hands the arm one joint target per action
(25 Hz by default). franky offers two ways to stream them:

* ``motion``: an asynchronous ``JointMotion`` per target; each new one preempts the last and
  Ruckig plans from the current state to a stop at the new target;
* ``impedance``: one ``JointImpedanceTracker`` whose reference is replaced per target, at
  franky's default stiffness (50 N m/rad on every joint);
* ``backend``: what the backend does: the targets go to the simulated arm's reference
  (``controller.JointPositionController``, straight segments at the speed limits), stepped at
  100 Hz, which a tracker at the backend's stiffness (``franky_arm.JOINT_STIFFNESS``) follows.

Both follow the same target sequence: a random walk of the kind a trained positioning policy
sends, steps of up to ``--step`` rad per joint, inside the FR3's limits. Measured per action,
sampled at 100 Hz from libfranka's state:

* tracking error: |q - target| at the end of each action cycle (rad; what the policy sees);
* jerkiness: the RMS of the joint jerk from the measured velocities at 100 Hz (rad/s^3).

    python benchmarks/franky_tracking.py --seconds 20 --rate 25

franky-sim runs in real time, so this takes about ``2 x seconds`` plus start-up.
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np

from robogym_ray.robots.panda.controller import JointPositionController
from robogym_ray.robots.panda.franky_arm import JOINT_STIFFNESS
from robogym_ray.robots.panda.franky_sim import FrankySim
from robogym_ray.robots.panda.model import LIMITS, READY


def targets(seconds: float, rate: float, step: float, seed: int) -> np.ndarray:
    """A random walk of joint targets from the ready pose (``seconds x rate`` rows)."""
    rng = np.random.default_rng(seed)
    walk = [READY.copy()]
    for _ in range(int(seconds * rate) - 1):
        nxt = walk[-1] + rng.uniform(-step, step, 7)
        walk.append(np.clip(nxt, READY - 0.5, READY + 0.5))  # well inside the FR3's limits
    return np.array(walk)


def follow(host: str, mode: str, plan: np.ndarray, rate: float) -> dict[str, float]:
    import franky

    robot = franky.Robot(host, realtime_config=franky.RealtimeConfig.Ignore)
    robot.relative_dynamics_factor = 0.2
    robot.move(franky.JointMotion(plan[0].tolist()))
    tracker, reference = None, None
    if mode == "impedance":  # franky's default stiffness, 50 N m/rad on every joint
        tracker = franky.JointImpedanceTracker(robot)
    elif mode == "backend":  # the simulated arm's reference at 100 Hz, Franka's example gains
        tracker = franky.JointImpedanceTracker(robot, stiffness=np.array(JOINT_STIFFNESS))
        reference = JointPositionController(LIMITS["fr3"].velocity, *_box())
        reference.reset(plan[0])
    period, sample = 1.0 / rate, 0.01
    q_log, dq_log, errors = [], [], []
    start = time.perf_counter()
    for i, target in enumerate(plan):
        if reference is not None:
            reference.command(target)
        elif tracker is not None:
            tracker.set_target(target)
        else:
            robot.move(franky.JointMotion(target.tolist()), asynchronous=True)
        cycle_end = start + (i + 1) * period
        while (now := time.perf_counter()) < cycle_end:
            if reference is not None:
                reference.step(sample)
                tracker.set_target(reference.position)
            state = robot.state
            q_log.append(np.array(state.q))
            dq_log.append(np.array(state.dq))
            time.sleep(min(sample, max(0.0, cycle_end - now)))
        errors.append(np.abs(np.array(robot.state.q) - target))
    if tracker is not None:
        tracker.stop()
    else:
        robot.stop()
    dq = np.array(dq_log)
    ddq = np.diff(dq, axis=0) / sample
    jerk = np.diff(ddq, axis=0) / sample
    err = np.array(errors)
    return {
        "tracking_error_median_rad": float(np.median(err)),
        "tracking_error_p90_rad": float(np.percentile(err, 90)),
        "jerk_rms_rad_s3": float(np.sqrt(np.mean(jerk**2))),
        "samples": len(q_log),
    }


def _box() -> tuple[np.ndarray, np.ndarray]:
    return LIMITS["fr3"].lower, LIMITS["fr3"].upper


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seconds", type=float, default=20.0)
    parser.add_argument("--rate", type=float, default=25.0, help="targets per second")
    parser.add_argument("--step", type=float, default=0.03, help="max change per target (rad)")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    plan = targets(args.seconds, args.rate, args.step, args.seed)
    results = {}
    for mode in ("motion", "impedance", "backend"):
        with FrankySim() as sim:  # a fresh arm for each, from the same pose
            results[mode] = follow(sim.host, mode, plan, args.rate)
    print(json.dumps({"args": vars(args), "results": results}, indent=2))


if __name__ == "__main__":
    main()
