"""The wire side every arm task shares, whatever the arm: SetState to a joint goal and its check,
the key-set check on every state, and the readers of joints, velocities and contacts.

robo-gym's arm servers (UR, Panda) report ``state_dict`` by name, so a task reads the joints
through the robot's key names (class attributes) and needs nothing else from the robot here.
What differs per arm stays in its tasks module: which keys SetState carries, joint order on the
wire, normalisation, spaces, rewards and drawing.
"""

from __future__ import annotations

from collections.abc import Collection, Mapping
from typing import ClassVar

import numpy as np

from robogym_ray.envs.base import RobotServerEnv, restart_hint
from robogym_ray.envs.frames import frame_xyz
from robogym_ray.errors import InvalidStateError
from robogym_ray.protocol import robot_server_pb2 as pb
from robogym_ray.protocol.client import RobotServerClient

RESET_TOLERANCE = 0.05
"""rad: a reset fails if any joint is farther than this from the request (robo-gym's check)."""


class ArmTask(RobotServerEnv):
    """A task on an arm whose server reports joints and a latched contact flag by name.

    A subclass sets the class attributes, ``keys`` (the rs_mode's exact key set) and
    ``start_joints`` in its ``__init__``, and the task methods of ``RobotServerEnv``.
    """

    rs_mode: ClassVar[str] = "only_robot"
    mode_keys: ClassVar[Mapping[str, Collection[str]]] = {}
    """The arm's key set of every rs_mode, to name the mode of a server in another one."""
    joint_names: ClassVar[tuple[str, ...]]
    """Joint names in the task's order, for messages."""
    position_keys: ClassVar[tuple[str, ...]]
    """``state_dict`` keys of the joint positions, in the task's order."""
    velocity_keys: ClassVar[tuple[str, ...]]
    """``state_dict`` keys of the joint velocities, in the task's order."""

    keys: frozenset[str]
    """The exact ``state_dict`` key set of ``rs_mode``."""
    start_joints: np.ndarray
    """The joints of the last reset (rad): where fixed joints are held."""

    # -- wire ------------------------------------------------------------------------------
    def _set_joint_goal(
        self,
        client: RobotServerClient,
        state_dict: Mapping[str, float],
        joints: np.ndarray,
        string_params: Mapping[str, str] | None = None,
        float_params: Mapping[str, float] | None = None,
    ) -> pb.State:
        """SetState with ``state_dict`` (which carries the goal ``joints``), then GetState and
        check that every joint arrived within ``RESET_TOLERANCE``.

        Raises:
            InvalidStateError: a joint is off, naming it, where it is and what was asked.
        """
        client.set_state(
            pb.State(
                state_dict=state_dict,
                string_params=dict(string_params or {}),
                float_params={k: float(v) for k, v in (float_params or {}).items()},
            )
        )
        msg = self.checked(client.get_state())
        reached = self.joints(msg)
        off = np.abs(reached - joints)
        if np.any(off > RESET_TOLERANCE):
            i = int(np.argmax(off))
            raise InvalidStateError(
                f"reset joint positions not within {RESET_TOLERANCE} rad of the request: "
                f"{self.joint_names[i]} at {reached[i]:.4f}, asked {joints[i]:.4f} "
                f"({self._where()})"
            )
        self.start_joints = np.asarray(joints, dtype=np.float64)
        return msg

    def set_joints(
        self,
        client: RobotServerClient,
        joints: np.ndarray,
        string_params: Mapping[str, str] | None = None,
        float_params: Mapping[str, float] | None = None,
    ) -> pb.State:
        """SetState to the joint goal ``joints`` (rad, task order) in the arm's own message (its
        keys, through ``_set_joint_goal``), with the episode's params; the state after it."""
        raise NotImplementedError

    def checked(self, msg: pb.State) -> pb.State:
        """``msg`` if its keys are exactly the rs_mode's; a server in another mode (or another
        robot's server) would otherwise be read as zeros or fail on a missing key later."""
        keys = set(msg.state_dict)
        if keys != self.keys:
            missing, extra = sorted(self.keys - keys), sorted(keys - self.keys)
            served = next((m for m, k in self.mode_keys.items() if set(k) == keys), None)
            # The mode is fixed when the server starts: only its command line can change it.
            fix = restart_hint({"rs_mode": self.rs_mode})
            how = (
                f"the server runs rs_mode {served!r}: {fix}"
                if served
                else f"if it is this arm's server, {fix}"
            )
            raise InvalidStateError(
                f"robot server state keys do not match rs_mode {self.rs_mode!r}: "
                f"missing {missing[:5]}{'...' if len(missing) > 5 else ''}, extra {extra[:5]} "
                f"({len(keys)} keys, expected {len(self.keys)}); {how} ({self._where()})"
            )
        return msg

    # -- actions as joint targets -----------------------------------------------------------
    active: np.ndarray
    """Mask (task order) of the joints the action moves; the others stay at their start."""

    def joint_targets(self, action: np.ndarray) -> np.ndarray:
        """The joint targets (rad, task order) this env sends for ``action`` now."""
        raise NotImplementedError

    def action_for(self, joints: np.ndarray) -> np.ndarray:
        """The action whose targets are ``joints`` (rad, task order), for the env as it is now.

        Commanding a joint configuration is not ``joints / limits`` in every task (robo-gym's
        positioning env maps wrist_1 onto [-3.48, 0.31] rad; the avoidance tasks add the action
        to a reference): this inverts the env's own map. Fixed joints' entries are ignored (they
        stay where the reset put them); values outside [-1, 1] mean the env cannot reach them.
        """
        q = np.asarray(joints, dtype=np.float64).reshape(-1)
        if q.shape != self.start_joints.shape:
            raise ValueError(f"action_for needs {self.start_joints.size} joints, got {q.size}")
        # Every task's map is affine per joint: two evaluations give offset and slope.
        n = int(np.count_nonzero(self.active))
        offset = self.joint_targets(np.zeros(n))[self.active]
        slope = self.joint_targets(np.ones(n))[self.active] - offset
        return ((q[self.active] - offset) / slope).astype(np.float32)

    # -- reading a state -------------------------------------------------------------------
    def joints(self, msg: pb.State) -> np.ndarray:
        """Joint positions (rad), the task's order."""
        return np.array([msg.state_dict[k] for k in self.position_keys], dtype=np.float64)

    def velocities(self, msg: pb.State) -> np.ndarray:
        """Joint velocities (rad/s), the task's order."""
        return np.array([msg.state_dict[k] for k in self.velocity_keys], dtype=np.float64)

    def collided(self, msg: pb.State) -> bool:
        """A contact since the last SetState. Real robots' bridges report none: always False."""
        return not self.real_robot and msg.state_dict["in_collision"] >= 0.5

    def _position(self, msg: pb.State) -> np.ndarray:
        return frame_xyz(msg.state_dict, "ee")
