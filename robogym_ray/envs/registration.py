"""Gymnasium ids ``RoboGymRay/<Task><Robot><Sim|Rob>-v0``, registered in a loop from one table.

Registration imports nothing heavy: entry points are strings, resolved by ``gymnasium.make``;
``gymnasium.make_vec(id, num_envs=K)`` builds ``envs.vector.RoboGymVectorEnv``.
``Sim`` ids get a simulated robot (in-process by default, see ``envs.servers``); ``Rob``
ids need ``rs_address="host:port"`` of a running robot server (real robot or emulation):
``gymnasium.make("RoboGymRay/ObstacleAvoidanceMir100Rob-v0", rs_address="10.0.0.5:50051")``.

No ``max_episode_steps`` is registered: each env truncates itself (so ``final_status`` is set)
at its own ``max_episode_steps``, which is also an env kwarg.
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
from gymnasium.envs.registration import EnvSpec, load_env_creator

from robogym_ray.envs.vector import vector_entry_point
from robogym_ray.errors import ConfigError
from robogym_ray.text import did_you_mean, quote, reason

_MIR = "robogym_ray.envs.mir100_tasks:"
_MIRS = "robogym_ray.envs.mir100_sectors:"
_UR = "robogym_ray.envs.ur_tasks:"
_URA = "robogym_ray.envs.ur_avoidance:"
_PANDA = "robogym_ray.envs.panda_tasks:"
_URM = "robogym_ray.envs.ur_modular:"
_PANDAM = "robogym_ray.envs.panda_modular:"
_DEPLOY = "robogym_ray.envs.ur_deploy_reach:"
_ISAAC_REWARD = "robogym_ray.envs.ur_isaac_reach_reward:"

RobotVariant = tuple[str, dict[str, Any]]
"""(robot as spelled in the id, env kwargs that pick it)."""
_MIR100: tuple[RobotVariant, ...] = (("Mir100", {}),)
_FRANKA: tuple[RobotVariant, ...] = (("Panda", {}), ("FR3", {"panda_model": "fr3"}))
"""The Franka arms: the Panda (robo-gym's) and the FR3 (the same task, its joint limits)."""


def _ur(*models: str) -> tuple[RobotVariant, ...]:
    """UR ids (``UR10``) and the ``ur_model`` kwarg (``ur10``) of the UR task classes."""
    return tuple((m, {"ur_model": m.lower()}) for m in models)


TASKS: tuple[tuple[str, str, tuple[RobotVariant, ...]], ...] = (
    # (task name, entry point, robots)
    ("NoObstacleNavigation", _MIR + "NoObstacleNavigationMir100", _MIR100),
    ("ObstacleAvoidance", _MIR + "ObstacleAvoidanceMir100", _MIR100),
    # The same task observing the nearest range per laser sector (not robo-gym's observation).
    ("ObstacleAvoidanceSectors", _MIRS + "ObstacleAvoidanceSectorsMir100", _MIR100),
    # Problem 2 of the paper (15 obs / 6 actions); the UR10 is the paper's robot.
    (
        "EndEffectorPositioning",
        _UR + "EndEffectorPositioningUR",
        _ur("UR3", "UR5", "UR10", "UR16e"),
    ),
    # robo-gym 2.0.1's EndEffectorPositioningURSim-v0 (27 obs / 5 actions).
    ("EndEffectorPositioningRoboGym", _UR + "EndEffectorPositioningRoboGymUR", _ur("UR5", "UR10")),
    ("EmptyEnvironment", _UR + "EmptyEnvironmentUR", _ur("UR5", "UR10")),
    # Avoidance tasks: object trajectories and reset poses are laid out for the UR5 workspace.
    ("BasicAvoidance", _URA + "BasicAvoidanceUR", _ur("UR5")),
    ("AvoidanceRaad2022", _URA + "AvoidanceRaad2022UR", _ur("UR5")),
    # robo-gym 2.1.0's Panda tasks (14 obs / 6 actions and 29 / 6), and on the FR3.
    ("EmptyEnvironment", _PANDA + "EmptyEnvironmentPanda", _FRANKA),
    ("EndEffectorPositioning", _PANDA + "EndEffectorPositioningPanda", _FRANKA),
    # robo-gym 2.1.0's modular UR envs (12 obs / 5 actions and 26 / 5).
    ("EmptyEnvironment2", _URM + "EmptyEnvironment2UR", _ur("UR5", "UR10")),
    ("EndEffectorPositioning2", _URM + "EndEffectorPositioning2UR", _ur("UR5", "UR10")),
    # robo-gym 2.1.0's Isaac Lab reach envs (25 obs / 6 actions and 32 / 7).
    ("IsaacReach", _URM + "IsaacReachUR", _ur("UR10")),
    ("IsaacReach", _PANDAM + "IsaacReachPanda", _FRANKA),
    # The UR10's on Isaac Lab's own reward, commands and ends (25 obs / 6 actions, as above).
    ("IsaacReachIsaacReward", _ISAAC_REWARD + "IsaacReachIsaacRewardUR", _ur("UR10")),
    # The same with a rotation tanh term priced like robo-gym's success tolerance.
    ("IsaacReachRotationTanh", _ISAAC_REWARD + "IsaacReachRotationTanhUR", _ur("UR10")),
    # And with finer position and rotation tanh terms, their stds the success tolerances.
    ("IsaacReachFineTanh", _ISAAC_REWARD + "IsaacReachFineTanhUR", _ur("UR10")),
    # Isaac Lab 3's Isaac-Deploy-Reach-UR10e-v0 (19 obs / 6 actions, 60 Hz).
    ("IsaacDeployReach", _DEPLOY + "IsaacDeployReachUR", _ur("UR10e")),
)
NONDETERMINISTIC = frozenset({"AvoidanceRaad2022"})
"""Tasks whose reset is not a function of the env seed alone: the sphere's spline is drawn by the
robot server's own RNG (spec c.2.4), so a second ``reset(seed=s)`` on the same server differs.
(A fresh embedded server is seeded from the first reset's seed, so fresh envs still agree.)"""
SAME_EPISODES = {"ObstacleAvoidanceSectors": "ObstacleAvoidance"}
"""Tasks that differ from another only in what they observe: the same reset seed gives the same
episode (start, target, obstacles, reward, ends), so their evaluations pair seed by seed."""
VARIANTS = {"Sim": False, "Rob": True}
"""Id suffix -> ``real_robot``."""


def env_id(task: str, robot: str, variant: str) -> str:
    return f"RoboGymRay/{task}{robot}{variant}-v0"


def episodes_of(env_id: str) -> str:
    """The env id whose episodes ``env_id`` runs: observation-only variants map to their base."""
    for task, base in SAME_EPISODES.items():
        prefix = f"RoboGymRay/{task}"
        if env_id.startswith(prefix):
            return f"RoboGymRay/{base}{env_id[len(prefix) :]}"
    return env_id


def register_all() -> list[str]:
    """Register every id (idempotent); returns them in table order."""
    ids = []
    for task, entry_point, robots in TASKS:
        for robot, robot_kwargs in robots:
            for variant, real in VARIANTS.items():
                kwargs: dict[str, Any] = {"real_robot": real, **robot_kwargs}
                name = env_id(task, robot, variant)
                if name not in gym.registry:
                    gym.register(
                        id=name,
                        entry_point=entry_point,
                        kwargs=kwargs,
                        nondeterministic=task in NONDETERMINISTIC,
                        vector_entry_point=vector_entry_point(name),
                    )
                ids.append(name)
    return ids


def variant_id(env_id: str, variant: str) -> str:
    """``...Sim-v0`` / ``...Rob-v0`` of the same task (``variant`` "sim" or "rob")."""
    if env_id.startswith("RoboGymRay/"):
        for suffix in ("Sim-v0", "Rob-v0"):
            if env_id.endswith(suffix):
                return env_id[: -len(suffix)] + variant.capitalize() + "-v0"
    hint = did_you_mean(env_id, register_all()) if isinstance(env_id, str) else ""
    raise ConfigError(f"{quote(env_id)} is not a RoboGymRay/<Task><Robot><Sim|Rob>-v0 id{hint}")


def env_spec(env_id: str) -> EnvSpec:
    """The registered spec of ``env_id``.

    Raises:
        ConfigError: ``env_id`` is not registered, naming the closest id that is (gymnasium's
            own hint misses a dropped namespace or version, and sees one namespace only).
    """
    register_all()
    try:
        return gym.spec(env_id)
    except gym.error.Error as err:
        hint = did_you_mean(env_id, gym.registry)
        why = "" if hint else f": {reason(str(err))}"
        raise ConfigError(f"unknown env id {quote(env_id)}{hint}{why}") from None


def server_spec_of(env_id: str) -> tuple[str, str | None, dict[str, str]]:
    """``(robot, scene, launch options)`` of the robot server ``env_id`` asks for: its
    ``server_spec()``, read from an env that is built but never connected.

    Raises:
        ConfigError: ``env_id`` is not registered.
    """
    spec = env_spec(env_id)
    cls = spec.entry_point if callable(spec.entry_point) else load_env_creator(spec.entry_point)
    # A Rob env with a placeholder address builds no server and opens no connection.
    env = cls(**{**spec.kwargs, "real_robot": True, "rs_address": "127.0.0.1:1"})
    try:
        return env.server_spec()
    finally:
        env.close()


def env_robot(env_id: str) -> str:
    """The registry name of the robot ``env_id`` drives (``mir100``, ``ur10`` ...).

    Raises:
        ConfigError: ``env_id`` is not registered.
    """
    return server_spec_of(env_id)[0]
