"""``IsaacReachIsaacRewardUR10Sim-v0``: robo-gym 2.1.0's UR10 reach (``IsaacReachUR``) on Isaac
Lab's own reward, commands, ends and resets (``isaac_reach_reward``), for training here; its
policies are scored on ``IsaacReachUR10Sim-v0``, whose spaces it keeps.
"""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np

from robogym_ray.envs.isaac_reach_reward import IsaacLabReachMDP, step_reward_range
from robogym_ray.envs.pose_commands import TanhTerm
from robogym_ray.envs.ur_common import JOINT_MAX
from robogym_ray.envs.ur_modular import IsaacReachUR
from robogym_ray.robots.ur.geometry import UR_MODELS

START_SCALE = 0.25
"""``reset_joints_by_scale``'s (0.75, 1.25) for the UR10: each default joint times U(1 +- this),
i.e. U(q +- this x |q|) per joint (zero joints stay at zero)."""
MAX_POSITION_ERROR = 2.6
"""A bound on tool1's error to a command (m): the commands lie within 0.85 m of base_link's origin
(the box's far corner), tool1 within the UR10's d1 + |a2| + |a3| + d4 + d5 + d6 = 1.69 m of it."""


class IsaacReachIsaacRewardUR(IsaacLabReachMDP, IsaacReachUR):
    """IsaacReachUR10's spaces with Isaac Lab's Isaac-Reach-UR10-v0 reward, 4-s commands and 12-s
    episodes, for training: its policies run on IsaacReachUR10Sim-v0 unchanged.

    ## Action space
    ``IsaacReachUR``'s: ``Box((6,), float32)``, joint targets ``joint_position + 0.5 * action``
    (rad), bounds ``(limit - joint_position) / 0.5``; 30 actions per second.

    ## Observation space
    ``IsaacReachUR``'s ``Box((25,), float32)``: joint positions relative to ``joint_position``,
    joint velocities, the command (xyz, quaternion w-x-y-z), the previous action. The command's
    slot changes when a new command is drawn.

    ## Reward
    Isaac Lab's, times its step dt (1/30 s): ``-0.2 d + 0.1 (1 - tanh(d / 0.1)) - 0.1 theta -
    1e-4 |a_t - a_t-1|^2 - 1e-4 |qdot|^2``, with ``d`` (m) and ``theta`` (rad) the errors of
    tool1 to the command in force during the step, ``a`` the raw actions (zeros before the
    first), ``qdot`` the joint velocities (rad/s). Within [-0.039, 0.0034] per step
    (``step_reward_range``). ``info``: ``dist_coord``, ``dist_rot`` (those errors),
    ``in_collision``; at the end of each command window ``window_position_error`` and
    ``window_rotation_error``.

    ## Episode end
    Only the time limit: truncated after 360 steps (12 s) with ``max_steps_exceeded``, or
    ``server_restarted``. A collision ends nothing (``IsaacLabReachMDP._evaluate``).

    ## Reset and commands
    Joints ``[0, -1.712, 1.712, 0, 0, 0]`` plus U(+-0.25 x |joint|) each (Isaac Lab's
    ``reset_joints_by_scale`` (0.75, 1.25); ``randomize_start``), at every reset. A new command
    every 120 steps (``resampling_time`` 4 s), after the step's reward, before its observation,
    drawn as ``IsaacReachUR`` draws its target. The server's target sphere marks the episode's
    first command only. Server: ``IsaacReachUR``'s.

    ## Arguments
    ``resampling_time`` and ``IsaacReachUR``'s.
    """

    pose_defaults: ClassVar[dict[str, Any]] = {
        **IsaacReachUR.pose_defaults,
        "continue_except_collision": False,
        "randomize_start": True,
        "random_joint_offset": tuple(START_SCALE * abs(q) for q in IsaacReachUR.default_joints),
    }


class IsaacReachRotationTanhUR(IsaacReachIsaacRewardUR):
    """``IsaacReachIsaacRewardUR`` with one more reward term, ``+0.1 (1 - tanh(theta / 0.25))``
    per second: Isaac Lab's position tanh carried over to the rotation, its std scaled by the
    ratio of robo-gym's success tolerances (0.05 rad / 0.02 m x 0.1 m). Isaac Lab's reward prices
    0.05 rad like 0.4 cm, robo-gym's success like 2 cm; with this term both cost ~0.024 per
    second near the command. Spaces, commands, ends and resets are ``IsaacReachIsaacRewardUR``'s.
    """

    tanh_terms = (TanhTerm("rotation", 0.1, 0.25),)


class IsaacReachFineTanhUR(IsaacReachRotationTanhUR):
    """``IsaacReachRotationTanhUR`` with two finer tanh terms, ``+0.1 (1 - tanh(d / 0.02))`` and
    ``+0.1 (1 - tanh(theta / 0.05))`` per second, their stds robo-gym's success tolerances: the
    coarse terms' slopes near the command (1.2 per m, 0.5 per rad) tell 1.35 cm from 1 cm by 0.004
    per second; these add 5 per m and 2 per rad there. Spaces, commands, ends and resets are
    ``IsaacReachIsaacRewardUR``'s.
    """

    tanh_terms = (
        *IsaacReachRotationTanhUR.tanh_terms,
        TanhTerm("position", 0.1, 0.02),
        TanhTerm("rotation", 0.1, 0.05),
    )


def return_range(
    discount: float = 0.99, task: type[IsaacLabReachMDP] = IsaacReachIsaacRewardUR
) -> tuple[float, float]:
    """The bounds of a discounted return of ``IsaacReachIsaacRewardUR10Sim-v0`` (episodes end
    only by the time limit, so the horizon is 1 / (1 - discount)), from its action bounds and
    the UR10's speed limits at the env's 0.2 of them, at 30 Hz; ``task``: the variant, whose
    tanh terms (>= 0, their weights at best) raise the best only."""
    default = np.asarray(IsaacReachUR.default_joints)
    scale = 0.5  # isaac_scale's default
    low, high = (-JOINT_MAX - default) / scale, (JOINT_MAX - default) / scale
    speeds = IsaacReachUR.velocity_scale * np.asarray(UR_MODELS["ur10"].max_velocity)
    rate = IsaacReachUR.action_rate
    worst, best = step_reward_range(low, high, speeds, MAX_POSITION_ERROR, rate)
    best += sum(term.weight for term in task.tanh_terms) / rate
    horizon = 1.0 / (1.0 - discount)
    return worst * horizon, best * horizon
