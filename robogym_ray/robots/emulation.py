"""An emulated real robot: a ``SimRobot`` made imperfect, the stand-in for hardware not at hand.

``robogym-ray serve --real-time --emulate-hardware`` serves a simulated MiR100 or UR arm through
``EmulatedRobot``, which differs from the simulation the policy was trained on the way a real
robot does, each difference configurable (``EmulationConfig``):

* **actuation latency**: every controller publication goes through a delay line of
  ``latency_ticks`` actuation ticks, so a command takes effect that many ticks after the command
  handler published it (a stop included); SetState empties the line (the driver drops queued
  commands on a reset);
* **actuation bias**: a constant offset added to every published command (a miscalibrated
  wheel-speed gain or joint zero offset);
* **dynamics**: velocity limits (MiR100 twist, UR joint speeds) and MiR100 acceleration limits
  scaled (the UR's controller is kinematic and has no acceleration limit to scale): the config
  fields the robot's card names (``RobotCard.emulation``);
* **sensor noise**: Gaussian noise on laser ranges (clipped to the scanner's range) and on the
  joint-encoder positions (the sensor groups the card names), from its own seeded RNG, so a
  run in simulated time is reproducible;
* **obstacles stay put** (MiR100): a real MiR server takes only the target from SetState, and
  robo-gym's Real env sends zeros for the three cube poses. Teleported to those zeros, the cubes
  would stand on the robot at the origin and pin it there. So all-zero cube poses leave the
  cubes where they stand; any other poses (the Sim env's resets, ``--variant sim``: an operator
  placing the cubes) still move them.

The wire protocol is untouched: state layouts, validation and errors are the wrapped robot's.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, replace

import numpy as np

from robogym_ray.config import check_ranges
from robogym_ray.errors import ConfigError
from robogym_ray.robots.base import RobotArguments, SimRobot, StateRequest, StateSnapshot
from robogym_ray.robots.card import EmulationHooks, RobotCard
from robogym_ray.robots.registry import CARDS

DEFAULT_LASER_RANGE = (0.05, 29.0)
"""Clip of noisy ranges when the wrapped robot does not say its own (m)."""


@dataclass(frozen=True)
class EmulationConfig:
    """How an emulated robot differs from the simulation (``--emulate-hardware``)."""

    laser_noise_sigma: float = 0.02
    """Std. dev. of Gaussian noise on every laser range (m); the S300 is specified at ~0.03."""
    joint_noise_sigma: float = 0.001
    """Std. dev. of Gaussian noise on reported joint positions (rad; joint encoders)."""
    latency_ticks: int = 1
    """Actuation ticks between the command handler's publication and its effect (MiR100: one
    tick = 0.1 s = one action; UR: one tick = 8 ms)."""
    velocity_scale: float = 0.95
    """Factor on the velocity limits (MiR100 |v|, |omega|; UR joint speeds)."""
    acceleration_scale: float = 0.9
    """Factor on the MiR100 acceleration limits (the UR has none to scale)."""
    actuation_bias: float = 0.005
    """Added to every element of every published command (m/s and rad/s, or rad)."""
    noise_seed: int | None = None
    """Seed of the noise; None = the server's seed."""

    def __post_init__(self) -> None:
        sigmas = ("laser_noise_sigma", "joint_noise_sigma")
        scales = ("velocity_scale", "acceleration_scale")
        v = {name: getattr(self, name) for name in (*sigmas, *scales)}
        check_ranges("EmulationConfig", [
            *((math.isfinite(v[n]) and v[n] >= 0, n, v[n], "finite and >= 0") for n in sigmas),
            *((math.isfinite(v[n]) and 0 < v[n] <= 2, n, v[n], "in (0, 2]") for n in scales),
            (self.latency_ticks >= 0, "latency_ticks", self.latency_ticks, ">= 0"),
            (math.isfinite(self.actuation_bias), "actuation_bias", self.actuation_bias, "finite"),
        ])  # fmt: skip


class EmulatedRobot(SimRobot):
    """``robot`` behind a command delay line, a bias and sensor noise (see the module docstring).

    Args:
        robot: the simulated robot (its dynamics already scaled, see ``emulate``).
        config: the emulation settings.
        seed: noise seed when ``config.noise_seed`` is None.
    """

    def __init__(self, robot: SimRobot, config: EmulationConfig, seed: int | None = None) -> None:
        self.inner = robot
        self.config = config
        self.name = robot.name
        self.handler_config = robot.handler_config
        self.sensor_periods = robot.sensor_periods
        self._rng = np.random.default_rng(
            config.noise_seed if config.noise_seed is not None else seed
        )
        self._delay: deque[np.ndarray | None] = deque()
        self._bias_in: np.ndarray | None = None
        self._bias_out: np.ndarray | None = None
        inner_config = getattr(robot, "config", None)
        card = _card_of(robot)
        self.hooks: EmulationHooks = card.emulation if card else EmulationHooks()
        fixed = self.hooks.fixed_obstacles
        self._obstacle_slots = card.state.slot(fixed) if card and fixed else None
        self._laser_range = (
            getattr(inner_config, "laser_range_min", DEFAULT_LASER_RANGE[0]),
            getattr(inner_config, "laser_range_max", DEFAULT_LASER_RANGE[1]),
        )
        self._clear_delay()

    # -- SimRobot interface -------------------------------------------------------------------
    def validate_action(self, action: np.ndarray) -> np.ndarray:
        return self.inner.validate_action(action)

    def set_state(self, request: StateRequest) -> None:
        self.inner.set_state(self._cubes_stay(request))  # raises before any change on bad input
        self._clear_delay()

    def publish(self, command: np.ndarray | None) -> None:
        self._delay.append(command)
        self.inner.publish(self._biased(self._delay.popleft()))

    def advance(self, dt: float) -> None:
        self.inner.advance(dt)

    def read_sensors(self, groups: Iterable[str] | None = None) -> dict[str, np.ndarray]:
        values = self.inner.read_sensors(groups)
        cfg, hooks = self.config, self.hooks
        if cfg.laser_noise_sigma > 0:
            low, high = self._laser_range
            for group in hooks.laser_groups:
                if group in values:
                    noisy = values[group] + self._rng.normal(
                        0.0, cfg.laser_noise_sigma, values[group].shape
                    )
                    values[group] = np.clip(noisy, low, high)
        group, n = hooks.joint_group, hooks.joint_count
        if cfg.joint_noise_sigma > 0 and group is not None and group in values:
            joints = values[group].copy()
            joints[:n] += self._rng.normal(0.0, cfg.joint_noise_sigma, n)
            values[group] = joints
        return values

    def compose(self, groups: Mapping[str, np.ndarray]) -> StateSnapshot:
        return self.inner.compose(groups)

    def arguments(self) -> RobotArguments:
        """The robot's own (``self.config`` is the emulation's, which has no modes)."""
        return self.inner.arguments()

    def close(self) -> None:
        self.inner.close()

    # -- internals ----------------------------------------------------------------------------
    def _cubes_stay(self, request: StateRequest) -> StateRequest:
        """``request`` with all-zero obstacle poses (the card's ``fixed_obstacles`` slot, the
        MiR100's cubes) replaced by where the obstacles stand."""
        current = getattr(self.inner, "obstacle_poses", None)
        state, slots = request.state, self._obstacle_slots
        if current is None or slots is None or len(state) < slots.stop:
            return request
        if not np.all(state[slots] == 0.0):
            return request
        poses = current()
        if poses.size == 0:  # a scene without cubes ignores the slots anyway
            return request
        state = state.copy()
        state[slots] = poses.ravel()
        return replace(request, state=state)

    def _clear_delay(self) -> None:
        # The line starts full of stops: for the first k ticks the robot keeps still.
        self._delay = deque([None] * self.config.latency_ticks)

    def _biased(self, command: np.ndarray | None) -> np.ndarray | None:
        if command is None or self.config.actuation_bias == 0.0:
            return command
        # The handler republishes one array object for all ticks of an action, and the UR arm
        # tells a repeat from a new action by identity; so a repeat gets the same biased object.
        if command is not self._bias_in:
            self._bias_in = command
            self._bias_out = np.asarray(command, dtype=np.float64) + self.config.actuation_bias
        return self._bias_out


def scale_dynamics(robot: SimRobot, config: EmulationConfig, seed: int | None) -> SimRobot:
    """``robot`` rebuilt with the config fields its card names (``EmulationHooks``) scaled.

    Robots are built from frozen configs, so scaling means a new robot of the same class from a
    replaced config; the original is closed. Unit scales return ``robot`` itself.
    """
    if config.velocity_scale == 1.0 and config.acceleration_scale == 1.0:
        return robot
    card = _card_of(robot)
    hooks = card.emulation if card else EmulationHooks()
    inner_config = getattr(robot, "config", None)
    if inner_config is None or not (hooks.velocity_fields or hooks.acceleration_fields):
        raise ConfigError(
            f"cannot scale the dynamics of {type(robot).__name__} ({robot.name}); use "
            "velocity_scale=1 and acceleration_scale=1"
        )
    scaled_fields = {
        f: getattr(inner_config, f) * config.velocity_scale for f in hooks.velocity_fields
    }
    scaled_fields |= {
        f: getattr(inner_config, f) * config.acceleration_scale for f in hooks.acceleration_fields
    }
    scaled: SimRobot = type(robot)(replace(inner_config, **scaled_fields), seed=seed)  # type: ignore[call-arg]
    robot.close()
    return scaled


def _card_of(robot: SimRobot) -> RobotCard | None:
    """The card of ``robot``; None for a robot outside the registry (no hooks: no scaling, no
    sensor noise)."""
    return CARDS.get(robot.name)


def emulate(robot: SimRobot, config: EmulationConfig, seed: int | None = None) -> EmulatedRobot:
    """The emulated real robot for the simulated ``robot`` (which it takes over)."""
    return EmulatedRobot(scale_dynamics(robot, config, seed), config, seed=seed)
