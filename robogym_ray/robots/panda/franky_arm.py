"""A real Franka arm (FR3) behind our robot server, through libfranka (franky).

``robogym-ray serve --robot fr3 --hardware franky --fci-host HOST`` serves robo-gym's
``RobotServer`` with this class in place of the PyBullet arm: the same wire contract as the
simulated Panda/FR3 (``robot.py``'s table), the same command handler and state buffer, paced by
the wall clock (the server's real-time mode; nothing is simulated here).

========================  ==================================================================
wire                      on the arm
========================  ==================================================================
SendAction                checked as the simulated arm checks it (7 values, finite, within the
                          model's limits: ``checks.py``), then the target of the simulated arm's
                          own reference (``controller.JointPositionController``: straight
                          joint-space segments at ``max_velocity_scale_factor`` x the speed
                          limits), which one ``JointImpedanceTracker`` follows at the actuation
                          rate (``benchmarks/franky_tracking.py``: smoother and closer than a
                          preempting ``JointMotion`` per target, and stable where raw targets
                          jumping every action are not)
SetState                  the joint goal checked, then a ``JointMotion`` to it at the reduced
                          ``relative_dynamics_factor`` of ``HardwareConfig`` (capped by the card)
GetState                  joints (q, dq, tau_J), the ``ee_frame`` pose from libfranka's
                          ``O_T_EE`` less its ``F_T_EE`` (so the frame is ours, checked against
                          our forward kinematics in the tests), contacts latched since SetState
                          (libfranka's joint/cartesian collision flags), the virtual target
RecoverFromErrors         franky's ``recover_from_errors()``, reconnecting first if the
                          connection was lost
========================  ==================================================================

Faults: any franky exception (``ControlException`` - reflexes such as
``communication_constraints_violation`` -, ``NetworkException``, a lost connection) latches a
fault. The arm is stopped (libfranka aborted the motion; ``stop()`` is sent where it still
listens), and every later SendAction, SetState and GetState is refused with the reason until
``RecoverFromErrors`` (an operator's ``robogym-ray resume-robot``). Refusals travel as robo-gym's
``success=false`` (``docs/protocol.md``), so the real-robot actor pauses on them. The server
serialises every call, so no lock is needed here.
"""

from __future__ import annotations

import contextlib
import logging
import time
from collections.abc import Iterable, Mapping
from typing import Any

import numpy as np

from robogym_ray.errors import RobotFaultError
from robogym_ray.robots.base import SimRobot, StateRequest, StateSnapshot
from robogym_ray.robots.command_handler import CommandHandlerConfig
from robogym_ray.robots.hardware import HardwareConfig
from robogym_ray.robots.objects import build_trajectory
from robogym_ray.robots.panda.checks import check_joint_action, check_joint_goal
from robogym_ray.robots.panda.config import PandaConfig, parse_options
from robogym_ray.robots.panda.controller import JointPositionController
from robogym_ray.robots.panda.model import HAND_YAW, LIMITS, quat_xyzw, rot_z
from robogym_ray.robots.panda.state import N_OBJECTS, compose_state, sensor_groups

log = logging.getLogger(__name__)

_IDENTITY = (0.0, 0.0, 0.0, 1.0)
JOINT_STIFFNESS = (600.0, 600.0, 600.0, 600.0, 250.0, 150.0, 50.0)
"""The tracker's joint stiffness (N m/rad): the gains of libfranka's joint impedance example
(``examples/joint_impedance_control.cpp``). franky's default, 50 on every joint, lets gravity pull
the shoulder several centimetres off its target (``benchmarks/franky_tracking.py``)."""


class FrankyArm(SimRobot):
    """One Franka arm driven through franky; ``name`` is the model (``fr3``).

    Args:
        config: the launch options, as the simulated arm parses them (rs_mode, action_mode,
            ee_frame, action rate).
        hardware: the arm's address and the reset's dynamics factor.
        lower, upper: the model's joint limits (rad), what commands and goals are checked on.
        velocity: the model's joint speed limits (rad/s), scaled by the config's
            ``max_velocity_scale_factor`` for the reference the arm follows.
    """

    def __init__(
        self,
        name: str,
        config: PandaConfig,
        hardware: HardwareConfig,
        lower: np.ndarray,
        upper: np.ndarray,
        velocity: np.ndarray,
    ) -> None:
        import franky  # the optional extra: only a hardware server needs it

        self._franky = franky
        self.name = name
        self.config = config
        self.hardware = hardware
        self.lower, self.upper = np.asarray(lower, float), np.asarray(upper, float)
        self.handler_config = CommandHandlerConfig(
            action_cycle=config.action_cycle, actuation_cycle=config.actuation_cycle
        )
        self.sensor_periods = {}
        self.groups = sensor_groups(config.rs_mode)
        self.fault = ""
        """Why the arm stopped ("" while healthy); latched until ``recover``."""
        self.faults = 0
        self._tracker: Any = None
        self._reference = JointPositionController(
            config.max_velocity_scale_factor * np.asarray(velocity, float), self.lower, self.upper
        )
        self._streaming = False
        """A command arrived since the last reset: the tracker follows the reference."""
        self._quiet_ticks = 0
        self._last_command: np.ndarray | None = None
        self._in_collision = False
        self._objects: list[Any] = [None] * N_OBJECTS[config.rs_mode]
        self._object_start = time.monotonic()
        self._rng = np.random.default_rng(0)
        self._robot = self._connect()
        self._last: dict[str, np.ndarray] = {}
        self._last = self.read_sensors()
        self._reference.reset(self._last["joints"][:7])

    # -- connection ---------------------------------------------------------------------------
    def _connect(self) -> Any:
        franky = self._franky
        try:
            realtime = (
                franky.RealtimeConfig.Enforce
                if self.hardware.enforce_realtime
                else franky.RealtimeConfig.Ignore
            )
            robot = franky.Robot(self.hardware.fci_host, realtime_config=realtime)
        except Exception as exc:  # noqa: BLE001 - franky raises its own and RuntimeError
            raise RobotFaultError(
                f"{self.name}: cannot connect to the arm's FCI at {self.hardware.fci_host}: {exc}"
            ) from None
        return robot

    def recover(self) -> None:
        """franky's ``recover_from_errors()``, on a fresh connection if the last one was lost;
        clears the fault. Raises RobotFaultError if the arm still refuses."""
        try:
            self._robot.recover_from_errors()
        except Exception:  # noqa: BLE001 - a lost connection cannot recover: connect again
            self._release()
            self._robot = self._connect()
            try:
                self._robot.recover_from_errors()
            except Exception as exc:  # noqa: BLE001
                raise RobotFaultError(f"{self.name}: recover_from_errors failed: {exc}") from None
        self.fault, self._tracker, self._last_command = "", None, None
        self._last = self.read_sensors()
        self._reference.reset(self._last["joints"][:7])
        self._streaming = False
        log.warning("%s: recovered from errors; the next SetState moves it to its goal", self.name)

    # -- actions ------------------------------------------------------------------------------
    def validate_action(self, action: np.ndarray) -> np.ndarray:
        self._refuse_if_faulted("SendAction")
        return check_joint_action(
            action, self.config.action_mode, self.lower, self.upper, self.name.upper()
        )

    def publish(self, command: np.ndarray | None) -> None:
        # None (no new command this tick): the reference keeps heading for its last target,
        # unless the client has gone quiet for two action cycles (a training stopped, a client
        # that vanished): then the arm stops where it is. Simulated time never passes without
        # actions; the wall clock does, and an arm must not finish a move nobody follows.
        if command is None:
            self._quiet_ticks += 1
            if self._quiet_ticks == 2 * self.handler_config.ticks_per_action:
                self._reference.command(self._reference.position)
            return
        self._quiet_ticks = 0
        if command is self._last_command or self.fault:
            return
        # The handler republishes the same array during one action: a delta becomes a target
        # once per action, from the reference, as the simulated arm computes it.
        self._last_command = command
        target = np.asarray(command, dtype=np.float64)
        if self.config.action_mode == "delta_pos":
            target = target + self._reference.position
        self._reference.command(target)  # clipped into the limits there
        self._streaming = True

    def advance(self, dt: float) -> None:
        # The arm's time is the wall clock's: the reference moves by one actuation tick and the
        # tracker is handed its position. Polling the motion surfaces a failure of libfranka's
        # control thread (a reflex aborts the tracker).
        if self.fault or not self._streaming:
            return
        self._reference.step(dt)
        try:
            if self._tracker is None:
                self._tracker = self._franky.JointImpedanceTracker(
                    self._robot,
                    stiffness=np.array(JOINT_STIFFNESS),
                    lower_joint_limits=self.lower,
                    upper_joint_limits=self.upper,
                )
            # No velocity feed-forward: the reference's velocity jumps at each new target, and
            # fed through the damping term it shook the arm (franky-sim, 2026-11-28).
            self._tracker.set_target(self._reference.position)
            self._robot.poll_motion()
        except Exception as exc:  # noqa: BLE001
            self._fail(f"following the joint reference failed: {exc}")

    # -- state ---------------------------------------------------------------------------------
    def set_state(self, request: StateRequest) -> None:
        goal = check_joint_goal(request, self.lower, self.upper, self.name.upper())
        rng = np.random.default_rng(self._rng.integers(2**63))
        trajectories = [
            build_trajectory(i, request.string_params, request.float_params, rng)
            for i in range(len(self._objects))
        ]
        self._refuse_if_faulted("SetState")
        franky = self._franky
        try:
            self._stop_tracker()
            self._robot.move(
                franky.JointMotion(
                    goal.tolist(),
                    relative_dynamics_factor=franky.RelativeDynamicsFactor(
                        self.hardware.dynamics_factor
                    ),
                )
            )
        except Exception as exc:  # noqa: BLE001
            self._fail(f"moving to the SetState goal failed: {exc}")
            self._refuse_if_faulted("SetState")
        for i, trajectory in enumerate(trajectories):
            if trajectory is not None:
                self._objects[i] = trajectory
        self._object_start = time.monotonic()
        self._in_collision = False
        self._last_command = None
        self._last = self.read_sensors()
        self._reference.reset(goal)
        self._streaming = False

    def read_sensors(self, groups: Iterable[str] | None = None) -> dict[str, np.ndarray]:
        wanted = self.groups if groups is None else tuple(groups)
        if self.fault:
            return {g: v for g, v in self._last.items() if g in wanted}
        try:
            state = self._robot.state
        except Exception as exc:  # noqa: BLE001 - "Net Exception" once the arm stops answering
            self._fail(f"reading the arm's state failed: {exc}")
            return {g: v for g, v in self._last.items() if g in wanted}
        if any(state.joint_collision) or any(state.cartesian_collision):
            self._in_collision = True
        out: dict[str, np.ndarray] = {}
        if "joints" in wanted:
            out["joints"] = np.concatenate([state.q, state.dq, state.tau_J]).astype(np.float64)
        if "ee" in wanted:
            out["ee"] = self._ee_pose(state)
        if "collision" in wanted:
            out["collision"] = np.array([1.0 if self._in_collision else 0.0])
        t = time.monotonic() - self._object_start
        for i, trajectory in enumerate(self._objects):
            if f"object_{i}" in wanted:
                xyz = trajectory.position(t) if trajectory is not None else np.zeros(3)
                out[f"object_{i}"] = np.concatenate([xyz, _IDENTITY])
        self._last = {**self._last, **out}
        return out

    def _ee_pose(self, state: Any) -> np.ndarray:
        """The ``ee_frame`` pose in the base frame: libfranka's end effector (``O_T_EE``, which
        includes the tool offset set in Desk, ``F_T_EE``) taken back to the flange, then the
        hand's mounting yaw for ``panda_hand``."""
        flange = np.asarray(state.O_T_EE.matrix) @ np.linalg.inv(np.asarray(state.F_T_EE.matrix))
        rotation = flange[:3, :3]
        if self.config.ee_frame == "panda_hand":  # as forward_kinematics turns the flange
            rotation = rotation @ rot_z(HAND_YAW)
        return np.concatenate([flange[:3, 3], quat_xyzw(rotation)])

    def compose(self, groups: Mapping[str, np.ndarray]) -> StateSnapshot:
        self._refuse_if_faulted("GetState")
        return compose_state(self.config.rs_mode, groups)

    # -- faults and shutdown -------------------------------------------------------------------
    def _refuse_if_faulted(self, rpc: str) -> None:
        if self.fault:
            raise RobotFaultError(
                f"{self.name} is stopped after an error ({self.fault}); {rpc} refused until an "
                f"operator recovers it (robogym-ray resume-robot, or the RecoverFromErrors RPC)"
            )

    def _fail(self, reason: str) -> None:
        if not self.fault:
            self.fault = reason
            self.faults += 1
            log.error("%s stopped: %s", self.name, reason)
        self._tracker = None
        # The motion is already aborted; tell the arm to stop where it still listens (after a
        # lost connection libfranka has stopped it).
        with contextlib.suppress(Exception):
            self._robot.stop()

    def _stop_tracker(self) -> None:
        tracker, self._tracker = self._tracker, None
        if tracker is not None:
            tracker.stop()

    def stop_arm(self) -> None:
        """Bring the arm to rest now (the server's shutdown, Ctrl-C or SIGTERM)."""
        try:
            self._stop_tracker()
            self._robot.stop()
        except Exception as exc:  # noqa: BLE001
            log.warning("%s: stopping the arm: %s", self.name, exc)

    def _release(self) -> None:
        # libfranka releases the arm when its Robot goes away; franky-sim, like the FCI,
        # serves one client at a time.
        self._tracker = None
        self._robot = None

    def close(self) -> None:
        self.stop_arm()
        self._release()


def make_franky_arm(model: str, options: Mapping[str, str], hardware: HardwareConfig) -> FrankyArm:
    """Registry factory of the ``franky`` backend: the arm ``model`` (``fr3``) at
    ``hardware.fci_host``, configured by launch-style ``options`` as the simulated one is."""
    limits = LIMITS[model]
    config = parse_options(model, None, options)
    return FrankyArm(model, config, hardware, limits.lower, limits.upper, limits.velocity)
