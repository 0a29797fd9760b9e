"""Task presets: short names for the paper's problems and D4PG settings that fit their rewards.

Any registered Gymnasium id with Box spaces also works as ``--task``; presets only add the
critic support (see ``robogym_ray.learner.config`` on choosing ``v_min``/``v_max``) and a few
hyperparameters known to suit the task.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import gymnasium as gym

from robogym_ray.config import merge_config
from robogym_ray.envs import ur_deploy_reach, ur_isaac_reach_reward
from robogym_ray.errors import ConfigError
from robogym_ray.learner.config import D4PGConfig
from robogym_ray.text import did_you_mean

if TYPE_CHECKING:
    from robogym_ray.training.config import TrainConfig


@dataclass(frozen=True)
class TaskPreset:
    env_id: str
    d4pg: Mapping[str, Any] = field(default_factory=dict)
    """D4PGConfig overrides that suit this task's reward scale and horizon."""
    description: str = ""
    """One line on what the task is (``robogym-ray tasks`` lists it)."""


# Rewards in [-16.3, 0], 200-step truncated episodes: support covers the discounted range;
# 1 learner step per env step (samples_per_insert == batch_size), as SB3/RLlib do here;
# (256, 256) nets cost ~40% less per step than (400, 300) and suffice for this task.
_PENDULUM = {
    "policy_hidden": (256, 256),
    "critic_hidden": (256, 256),
    "v_min": -1500.0,
    "v_max": 0.0,
    "policy_lr": 1e-3,
    "critic_lr": 1e-3,
    "samples_per_insert": 256.0,
    "target_tau": 0.005,
    "min_replay_size": 1000,
    "importance_beta_steps": 20_000,
    "sigma": 0.2,
    "n_step": 3,
}
_POSITIONING = {"v_min": -250.0, "v_max": 250.0, "layer_norm": True, "min_replay_size": 500}
_PANDA_POSITIONING = {**_POSITIONING, "v_min": -5.0, "v_max": 5.0}
_ISAAC_REACH = {**_POSITIONING, "v_min": -20.0, "v_max": 5.0}


def _support(return_range: Callable[[float], tuple[float, float]]) -> dict[str, float]:
    """``[v_min, v_max]``: the bounds of a task's discounted return (discount 0.99) over the
    env's action bounds (the rule of ``learner.config``), rounded outwards to whole units."""
    worst, best = return_range(0.99)
    return {"v_min": float(math.floor(worst)), "v_max": float(math.ceil(best))}


# [-9, 4] for the UR10e at its streamed actions' bounds of [-1, 1] (it was [-138, 4] at the
# trajectory bounds of before).
_DEPLOY_REACH = {**_POSITIONING, **_support(ur_deploy_reach.return_range)}


def _isaac_reach_support(task: type[ur_isaac_reach_reward.IsaacLabReachMDP]) -> dict[str, float]:
    """The positioning settings with the support of an IsaacReach variant's returns."""
    return {**_POSITIONING, **_support(lambda d: ur_isaac_reach_reward.return_range(d, task))}


# [-4, 1]: per step (-0.2 x 2.6 m - 0.1 x pi rad - 1e-4 x 3316 (every action jumping across its
# +-25 bounds) - 1e-4 x 1.93 (every joint at 0.2 of its speed limit)) / 30 = -0.0389 at worst,
# 0.1 / 30 = 0.0033 at best (on the command, still), times the horizon of 100 steps.
_ISAAC_REACH_ISAAC_REWARD = _isaac_reach_support(ur_isaac_reach_reward.IsaacReachIsaacRewardUR)
# [-4, 1] too: the rotation tanh term adds 0.1 / 30 to the best step, 0.0067 x 100 = 0.67.
_ISAAC_REACH_ROTATION_TANH = _isaac_reach_support(ur_isaac_reach_reward.IsaacReachRotationTanhUR)
# [-4, 2]: the two finer terms add 0.2 / 30 more, 0.0133 x 100 = 1.33.
_ISAAC_REACH_FINE_TANH = _isaac_reach_support(ur_isaac_reach_reward.IsaacReachFineTanhUR)
_NAVIGATION = {"v_min": -300.0, "v_max": 450.0, "layer_norm": True, "min_replay_size": 500}

TASKS: dict[str, TaskPreset] = {
    # Navigation: shaping sums to ~50 x start distance (<= ~350), success +100, collision -200.
    "navigation": TaskPreset(
        "RoboGymRay/ObstacleAvoidanceMir100Sim-v0",
        _NAVIGATION,
        "MiR100 crosses the 6 x 8 m lab to a target past three cubes (the paper's problem 1)",
    ),
    # The same task observing the nearest laser return per sector (envs/mir100_sectors.py).
    "navigation-sectors": TaskPreset(
        "RoboGymRay/ObstacleAvoidanceSectorsMir100Sim-v0",
        _NAVIGATION,
        "navigation, observing the nearest laser return per sector (not robo-gym's observation)",
    ),
    # Positioning: progress 50/m over <= ~2.4 m, +100 at the goal, -200 on collision.
    "positioning": TaskPreset(
        "RoboGymRay/EndEffectorPositioningUR10Sim-v0",
        _POSITIONING,
        "UR10 brings its end effector to a target point (the paper's problem 2)",
    ),
    # robo-gym 2.1.0's Panda positioning: the positioning recipe with the critic's support fitted
    # to its much smaller returns (-0.005/m per step over <= 300 steps, +2 at the goal, -1 on
    # collision: within about [-3.3, 2]); +-250 would put them all in ~1 of 51 atoms.
    "panda-positioning": TaskPreset(
        "RoboGymRay/EndEffectorPositioningPandaSim-v0",
        _PANDA_POSITIONING,
        "Franka Panda brings its hand to a target point (robo-gym 2.1.0); the quickest to learn",
    ),
    # The same task on the Franka Research 3 (its joint limits, the Panda's kinematics): the same
    # rewards, so the same settings, those that trained the Panda on 2 cores.
    "fr3-positioning": TaskPreset(
        "RoboGymRay/EndEffectorPositioningFR3Sim-v0",
        _PANDA_POSITIONING,
        "Franka FR3 brings its hand to a target point: the Panda's task with the FR3's limits",
    ),
    # robo-gym 2.1.0's Isaac Lab reach (UR10): the positioning recipe, support fitted to its
    # returns. Steps cost 0.005/m + 0.05/rad (measured over 30 random, zero and bang-bang
    # episodes: -0.161 to -0.027; at most ~-0.167 with pi rad off), success +2 and collision -1
    # end the episode; truncation at 600 steps bootstraps, so the worst value is ~-0.167 x 100
    # (gamma 0.99) = -16.7 and the best +2: [-20, 5] leaves a margin (atoms 0.5 apart).
    "isaac-reach-ur10": TaskPreset(
        "RoboGymRay/IsaacReachUR10Sim-v0",
        _ISAAC_REACH,
        "UR10 reaches a pose: robo-gym 2.1.0's port of Isaac Lab's Isaac-Reach-UR10-v0",
    ),
    # The same UR10 reach on Isaac Lab's own reward and ends (envs/ur_isaac_reach_reward.py): a
    # tracking reward times dt = 1/30 s, a new pose every 4 s, 12-s episodes that end only by
    # time, so no crash ends a costly search; the same spaces, so its policies are scored on
    # IsaacReachUR10Sim-v0 (`evaluate --env-id`). The positioning recipe with the support of
    # _ISAAC_REACH_ISAAC_REWARD.
    "isaac-reach-ur10-isaac-reward": TaskPreset(
        "RoboGymRay/IsaacReachIsaacRewardUR10Sim-v0",
        _ISAAC_REACH_ISAAC_REWARD,
        "isaac-reach-ur10 on Isaac Lab's reward and 4-s commands; a goal task (--relabel-goals)",
    ),
    # The same with one more term, +0.1 (1 - tanh(theta / 0.25)) per second: Isaac Lab's position
    # tanh carried over to the rotation, so that 2.1.0's success tolerances (0.02 m, 0.05 rad)
    # cost alike; Isaac Lab's reward prices 0.05 rad like 0.4 cm (results-log.md, 2026-11-29).
    "isaac-reach-ur10-rotation-tanh": TaskPreset(
        "RoboGymRay/IsaacReachRotationTanhUR10Sim-v0",
        _ISAAC_REACH_ROTATION_TANH,
        "isaac-reach-ur10-isaac-reward with the rotation priced like 2.1.0's success; a goal task",
    ),
    # The same with two finer terms, +0.1 (1 - tanh(d / 0.02)) and +0.1 (1 - tanh(theta / 0.05))
    # per second: their stds the success tolerances, for the last centimetre and 0.05 rad.
    "isaac-reach-ur10-fine-tanh": TaskPreset(
        "RoboGymRay/IsaacReachFineTanhUR10Sim-v0",
        _ISAAC_REACH_FINE_TANH,
        "isaac-reach-ur10-rotation-tanh with finer tanh terms at the success tolerances",
    ),
    # Isaac Lab 3's deploy reach (UR10e): its keypoint reward times 1/60 s per step, plus the
    # action and action-rate L2 terms; episodes end only by the time limit, so the support is the
    # per-step range times the horizon, at the action bounds of [-1, 1] (_DEPLOY_REACH).
    # A first preset, [-6, 4], left out the action terms, which dominated at the wide trajectory
    # bounds of before: that run's returns (~-26 discounted) lay below it (results-log.md,
    # 2026-11-26).
    "isaac-deploy-reach-ur10e": TaskPreset(
        "RoboGymRay/IsaacDeployReachUR10eSim-v0",
        _DEPLOY_REACH,
        "UR10e tracks a pose with 60 Hz joint targets: Isaac Lab 3's Isaac-Deploy-Reach-UR10e-v0",
    ),
    # Pendulum: the preset proven by benchmarks/pendulum.py (the local trainer applies it too).
    "pendulum": TaskPreset(
        "Pendulum-v1", _PENDULUM, "Gymnasium's pendulum swing-up: no robot, a check in minutes"
    ),
}


def resolve_task(task: str) -> TaskPreset:
    """A preset by short name, or a bare preset for a registered env id (clear error if none)."""
    if task in TASKS:
        return TASKS[task]
    import robogym_ray  # noqa: F401 - registers RoboGymRay/* ids

    if task in gym.registry:
        return TaskPreset(task)
    # The example is a preset's id: the alphabetically first ones are obscure variants.
    raise ConfigError(
        f"unknown task {task!r}{did_you_mean(task, [*TASKS, *gym.registry])}: use a short name "
        f"({', '.join(TASKS)}) or a registered Gymnasium id, e.g. {TASKS['navigation'].env_id} "
        "(robogym-ray tasks lists them)"
    )


def d4pg_for(
    preset: TaskPreset,
    overrides: Mapping[str, Any] | None = None,
    train: TrainConfig | None = None,
) -> D4PGConfig:
    """D4PGConfig = defaults <- task preset <- user overrides (config file) <- the batch that
    ``train.batch_per_worker`` asks for."""
    base = merge_config(D4PGConfig, preset.d4pg, f"preset {preset.env_id}")
    d4pg = merge_config(D4PGConfig, overrides or {}, "d4pg settings", base=base)
    if train is not None and train.batch_per_worker:
        batch = {"batch_size": train.batch_per_worker * train.rollout_workers}
        d4pg = merge_config(D4PGConfig, batch, "--batch-per-worker", base=d4pg)
    return d4pg
