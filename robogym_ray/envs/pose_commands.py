"""Isaac Lab's pose commands on a schedule, for any ``PoseTask``: ``UniformPoseCommand`` with
``resampling_time_range=(T, T)``, a new command every T seconds of env time.

Isaac Lab's ``ManagerBasedRLEnv.step`` computes the step's reward, then resamples the commands
whose time is up, then observes: so a step's reward scores the command in force during it
(``scored_pose``), and the observation that follows already shows the next one. The last window
ends with the episode, which draws its own first command at the reset.

Both Isaac Lab tasks here use it: the deploy reach (``ur_deploy_reach``) and the UR10 reach on
Isaac Lab's own reward (``isaac_reach_reward``).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, ClassVar, Literal

import numpy as np
from scipy.spatial.transform import Rotation

from robogym_ray.envs.base import StepInfo
from robogym_ray.envs.modular import PoseTask
from robogym_ray.envs.outcomes import WINDOW_KEYS
from robogym_ray.envs.pose_targets import sample_target_pose
from robogym_ray.errors import ConfigError
from robogym_ray.protocol import robot_server_pb2 as pb
from robogym_ray.protocol.client import RobotServerClient


def pose_errors(
    pos: np.ndarray, rotation: Rotation, goal_pos: np.ndarray, goal_rotation: Rotation
) -> tuple[np.ndarray, np.ndarray]:
    """Position (m) and rotation (rad, the shortest path: Isaac Lab's
    ``quat_error_magnitude``) errors of poses to goals, row by row (hindsight relabelling
    scores many at once)."""
    position = np.linalg.norm(np.asarray(pos, dtype=np.float64) - goal_pos, axis=-1)
    return position, (rotation * goal_rotation.inv()).magnitude()


def pose_error(pos: np.ndarray, rotation: Rotation, goal: np.ndarray) -> tuple[float, float]:
    """``pose_errors`` of one pose to ``goal`` (xyz, quaternion x-y-z-w)."""
    position, turn = pose_errors(pos, rotation, goal[:3], Rotation.from_quat(goal[3:]))
    return float(position), float(turn)


@dataclass(frozen=True)
class TanhTerm:
    """A reward term ``weight (1 - tanh(error / std))`` per second, beyond Isaac Lab's: >= 0, its
    weight on the command, its slope near it ``weight / std``."""

    error: Literal["position", "rotation"]
    """Which error it prices: the frame's position (m) or rotation (rad) to the command."""
    weight: float
    std: float


class PoseCommands(PoseTask):
    """``PoseTask`` whose target is redrawn every ``resampling_time`` seconds of env time.

    Args:
        resampling_time: seconds between commands (default 4.0): a whole number of steps at
            the env's action rate, at least one.
        **kwargs: ``PoseTask``'s.
    """

    tanh_terms: ClassVar[tuple[TanhTerm, ...]] = ()
    """Reward terms beyond Isaac Lab's (none: Isaac Lab's reward), for the task variants."""

    def __init__(self, *, resampling_time: float = 4.0, **kwargs: Any) -> None:
        self.resampling_time = float(resampling_time)
        self.scored_pose = np.zeros(7)
        """The command in force during the last step (the observation may show the next)."""
        super().__init__(**kwargs)
        self.prev_action = np.zeros(self.action_space.shape)
        """The action of the step before the last (Isaac Lab's ``prev_action``)."""
        steps = self.resampling_time * self.action_rate
        if not (math.isfinite(steps) and steps >= 1):
            raise ConfigError(
                f"resampling_time must be at least one step (1/{self.action_rate:g}"
                f" s), got {resampling_time!r}"
            )
        self.window = round(steps)
        """Steps per command."""

    def _send(self, client: RobotServerClient, action: np.ndarray) -> pb.State:
        self.prev_action = self.last_action.copy()
        msg = super()._send(client, action)
        self.scored_pose = self.target_pose.copy()
        step = self.elapsed_steps + 1
        if step % self.window == 0 and step < self.max_episode_steps:
            # Isaac Lab resamples after the step's reward, before its observation.
            self._new_command()
        return msg

    def _prepare(self, options: Mapping[str, Any]) -> tuple[dict[str, str], dict[str, float]]:
        prepared = super()._prepare(options)  # the first command (or the ee_target_pose option)
        self.prev_action = np.zeros(self.action_space.shape)
        self.scored_pose = self.target_pose.copy()
        return prepared

    def _new_command(self) -> None:
        self.target_pose = sample_target_pose(self.np_random, self.pose_cfg, self.workspace())
        self.target = self.target_pose[:3].copy()

    def window_errors(self, position: float, rotation: float) -> StepInfo:
        """``WINDOW_KEYS`` (m, rad) on a command window's last step, the episode's included;
        nothing on the other steps."""
        if self.elapsed_steps % self.window == 0 or self.elapsed_steps >= self.max_episode_steps:
            return dict(zip(WINDOW_KEYS, (position, rotation), strict=True))
        return {}

    def tanh_per_second(self, position: Any, rotation: Any) -> Any:
        """The sum of ``tanh_terms`` before the dt, of position and rotation errors (m, rad):
        floats, or arrays of them (hindsight relabelling scores many commands at once)."""
        errors = {"position": position, "rotation": rotation}
        total: Any = 0.0
        for term in self.tanh_terms:
            error = np.asarray(errors[term.error], np.float64)
            total = total + term.weight * (1.0 - np.tanh(error / term.std))
        return total
