"""Isaac Lab's own reach MDP on robo-gym 2.1.0's reach spaces, robot-agnostic: the reward, command
schedule, episode length and resets of ``Isaac-Reach-UR10-v0`` for an ``IsaacReachTask``, whose
observation and action spaces stay the same, so a policy trained on it runs on the robo-gym env
unchanged (and an Isaac Lab export runs on either). ``ur_isaac_reach_reward`` binds it to the
UR10 (``IsaacReachIsaacRewardUR10Sim-v0``).

Read from isaac-sim/IsaacLab, ``isaaclab_tasks/manager_based/manipulation/reach/``:
``reach_env_cfg.py`` (032e26b7), ``mdp/rewards.py`` (0f83bb4f), ``config/ur_10/
joint_pos_env_cfg.py`` (032e26b7 and b9fb730a), ``config/ur_10/agents/rsl_rl_ppo_cfg.py``
(0bc6b5da); and the reward manager's ``compute(dt)``, which multiplies every term by the step dt:

* rewards: ``position_command_error`` (L2, m) -0.2; ``position_command_error_tanh``
  (``1 - tanh(d / 0.1)``) +0.1; ``orientation_command_error`` (shortest-path angle, rad) -0.1;
  ``action_rate_l2`` -1e-4; ``joint_vel_l2`` -1e-4; each times dt = 1/60 s x decimation 2;
* commands: ``UniformPoseCommand``, resampled every 4 s (``pose_commands``);
* terminations: ``time_out`` only, ``episode_length_s`` 12;
* events: ``reset_joints_by_scale``, the default joints times U(0.75, 1.25) at each reset.

Not mirrored: the ``CurriculumCfg`` that raises the action-rate weight to -0.005 and the
joint-velocity weight to -0.001 after 4,500 steps of the vectorised env (iteration ~188 of the
1,000 rsl_rl runs), and the U(+-0.01) noise on the observed joints (``enable_corruption``).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation

from robogym_ray.envs.base import StepInfo
from robogym_ray.envs.frames import frame_rotation, frame_xyz, quat_from_order, quat_to_order
from robogym_ray.envs.isaac_reach import COMMAND_QUAT_ORDER
from robogym_ray.envs.pose_commands import PoseCommands, pose_error, pose_errors
from robogym_ray.protocol import robot_server_pb2 as pb

POSITION_WEIGHT, TANH_WEIGHT, TANH_STD, ROTATION_WEIGHT = -0.2, 0.1, 0.1, -0.1
ACTION_RATE_WEIGHT, JOINT_VEL_WEIGHT = -1e-4, -1e-4
"""``Isaac-Reach-UR10-v0``'s reward weights (per second: the env multiplies them by its dt)."""


def tracking_per_second(position: Any, rotation: Any) -> Any:
    """The reward's command terms before the dt, of position and rotation errors (m, rad):
    floats, or arrays of them (hindsight relabelling scores many commands at once)."""
    tanh = TANH_WEIGHT * (1.0 - np.tanh(np.asarray(position, np.float64) / TANH_STD))
    return POSITION_WEIGHT * position + tanh + ROTATION_WEIGHT * rotation


def effort_per_second(action_change: np.ndarray, joint_velocity: np.ndarray) -> float:
    """The reward's terms that no command changes, before the dt: the change of the raw action
    from the step before and the joint velocities (rad/s)."""
    effort = ACTION_RATE_WEIGHT * float(np.sum(np.square(action_change)))
    return effort + JOINT_VEL_WEIGHT * float(np.sum(np.square(joint_velocity)))


def reward_per_second(
    position: float, rotation: float, action_change: np.ndarray, joint_velocity: np.ndarray
) -> float:
    """Isaac Lab's reach reward before the dt: position and rotation errors (m, rad) to the
    command, the change of the raw action from the step before, the joint velocities (rad/s)."""
    tracking = float(tracking_per_second(position, rotation))
    return tracking + effort_per_second(action_change, joint_velocity)


def step_reward_range(
    action_low: np.ndarray,
    action_high: np.ndarray,
    max_velocity: np.ndarray,
    max_position_error: float,
    rate: float,
) -> tuple[float, float]:
    """The bounds of one step's reward (per-second reward / ``rate``, actions per second).

    Best: on the command, the action unchanged, the arm still (the tanh term's 0.1). Worst: the
    position error at ``max_position_error`` (m), the rotation error at pi, the action jumping
    from one bound to the other on every joint, every joint at ``max_velocity`` (rad/s).
    """
    span = np.asarray(action_high, np.float64) - np.asarray(action_low, np.float64)
    worst = reward_per_second(max_position_error, math.pi, span, np.asarray(max_velocity))
    best = reward_per_second(0.0, 0.0, np.zeros(1), np.zeros(1))
    return worst / rate, best / rate


class IsaacLabReachMDP(PoseCommands):
    """Isaac Lab's reach reward and ends on an ``IsaacReachTask`` (see the module docstring).

    It is a goal task for hindsight relabelling (``experience/relabel.py``): ``info`` carries
    the pose reached (``achieved_goal``, in the observation's command layout: xyz, quaternion
    w-x-y-z) and the reward's command-free part (``effort``); ``compute_reward`` scores any
    command the way ``_evaluate`` scores the one in force.
    """

    max_episode_steps = 360  # 12 s at 30 Hz: Isaac Lab's dt of 1/60 s x decimation 2
    # A new command every 4 s: PoseCommands' resampling_time default, Isaac Lab's.
    reward_info_keys = ("effort",)
    ends_on_goal = False

    @property
    def goal_slice(self) -> slice:
        """The command's place in the observation (after positions and velocities)."""
        start = 2 * (self.lower.size + len(self.extra))
        return slice(start, start + 7)

    def compute_reward(
        self, achieved_goal: np.ndarray, desired_goal: np.ndarray, info: Mapping[str, Any]
    ) -> np.ndarray:
        """The step rewards for poses reached and commands (rows of xyz + quaternion w-x-y-z)
        with ``info["effort"]``, per step (the dt applied)."""
        achieved = np.atleast_2d(np.asarray(achieved_goal, np.float64))
        desired = np.atleast_2d(np.asarray(desired_goal, np.float64))
        here, there = (
            Rotation.from_quat(quat_from_order(r[:, 3:], COMMAND_QUAT_ORDER))
            for r in (achieved, desired)
        )
        position, rotation = pose_errors(achieved[:, :3], here, desired[:, :3], there)
        per_second = self._tracking(position, rotation) + np.asarray(info["effort"])
        return per_second / self.action_rate

    def _tracking(self, position: Any, rotation: Any) -> Any:
        """``tracking_per_second`` plus this task's ``tanh_terms``."""
        return tracking_per_second(position, rotation) + self.tanh_per_second(position, rotation)

    def _evaluate(
        self, msg: pb.State, obs: np.ndarray, action: np.ndarray
    ) -> tuple[float, str | None, StepInfo]:
        """Isaac Lab's reward times the step dt; no end but the time limit. A contact with the
        table or the arm itself ends nothing (Isaac Lab's task has no such term; in Isaac Sim
        the table stops the arm, here the kinematic arm passes through it): ``in_collision``
        says it happened (latched until the next reset)."""
        sd = msg.state_dict
        xyz, turn = frame_xyz(sd, "ee"), frame_rotation(sd, "ee")
        position, rotation = pose_error(xyz, turn, self.scored_pose)
        change = np.asarray(action, dtype=np.float64) - self.prev_action
        effort = effort_per_second(change, self.velocities(msg))
        reward = float(self._tracking(position, rotation)) + effort
        reached = turn.as_quat(canonical=self.pose_cfg.ee_rotation_quat_unique)
        info: StepInfo = {
            **self._info(msg),
            "dist_coord": position,
            "dist_rot": rotation,
            "in_collision": self.collided(msg),
            "achieved_goal": np.concatenate([xyz, quat_to_order(reached, COMMAND_QUAT_ORDER)]),
            "effort": effort,
            **self.window_errors(position, rotation),
        }
        return reward / self.action_rate, None, info
