"""Base of every robogym-ray environment: a Gymnasium env in front of one robot server.

Sim and Real are one class with a switch, because the two differ in *where the server comes
from* and *what the env may assume*, not in the task:

* **Sim** (``real_robot=False``): the server comes from a ``ServerProvider`` (default: the robot
  core in this process, built on first reset and called without the wire, so
  ``gymnasium.make(id)`` needs nothing running; ``provider=EmbeddedServerProvider()`` puts a
  gRPC robot server in between; ``rs_address=`` pins one). A ``RobotServerError`` mid-episode
  is reported to the lease, a new lease is acquired and the episode ends with ``truncated=True`` and
  ``info["final_status"] == "server_restarted"`` - a restart is invisible otherwise. A failure in
  ``reset`` is retried once on a fresh lease.
* **Real** (``real_robot=True``): ``rs_address="host:port"`` of a running robot server is
  required. Nothing is started or restarted (errors propagate), and tasks skip every check the
  real robot cannot sense (see each task).

Actions are clipped to the action space; a wrong shape, NaN or inf raises
``InvalidActionError`` before anything is sent. Observations outside the observation space (NaN
included) raise ``InvalidStateError`` naming the index, value and bounds, as robo-gym's envs do.

Rendering: ``render_mode="rgb_array"`` returns a ``uint8`` H x W x 3 frame of the scene drawn
from the last state message (``envs/render``: a digital twin, so Real envs render too);
``"human"`` shows the frames in a window after every reset and step (it needs a display and
fails at construction without one). ``render_config`` sets the size and camera.

Episodes: the step limit (``max_episode_steps``) ends an episode with ``truncated=True``.
robo-gym instead reports ``done=True`` (there is no truncation in robo-gym); we truncate so
that learners bootstrap from the last state. ``info["final_status"]`` is set on the last step.
"""

from __future__ import annotations

import math
import os
from abc import abstractmethod
from collections.abc import Callable, Mapping
from typing import Any, ClassVar

import gymnasium as gym
import numpy as np

from robogym_ray.envs.outcomes import MAX_STEPS, SERVER_RESTARTED
from robogym_ray.envs.render import HumanWindow, RenderConfig, check_display
from robogym_ray.envs.servers import (
    ServerLease,
    ServerProvider,
    StaticServerProvider,
    default_provider,
)
from robogym_ray.errors import ConfigError, InvalidStateError, RobotServerError
from robogym_ray.protocol import robot_server_pb2 as pb
from robogym_ray.protocol.client import Deadlines, RobotServerClient, check_action
from robogym_ray.protocol.tls import read_ca

StepInfo = dict[str, Any]


def restart_hint(options: Mapping[str, str]) -> str:
    """How to restart a robot server with ``options``, for both kinds a user may run."""
    ours = " ".join(f"{k}={v}" for k, v in options.items())
    ros = " ".join(f"{k}:={v}" for k, v in options.items())
    return f"restart it with --option {ours}, or {ros} for robo-gym's launch file"


class RobotServerEnv(gym.Env[np.ndarray, np.ndarray]):
    """Common Sim/Real machinery; subclasses define the task (see the module docstring).

    Args:
        real_robot: Real variant (needs ``rs_address``; no server management).
        rs_address: ``host:port`` of a running robot server (Real: required; Sim: optional).
        provider: where a Sim env gets servers (default ``InProcessServerProvider()``; the
            training program passes its own).
        token: shared token for the server (gRPC metadata ``robogym-token``).
        tls_ca: the CA of a TLS server's certificate (``serve --tls-cert``): a PEM file's path
            or its bytes, read now; the server is verified against it. None: a plain channel.
        deadlines: per-RPC deadlines (default: ``Deadlines.fast()`` for the default embedded
            server, robo-gym's (spec a.2) for any other server).
        server_seed: seed of an embedded server's own randomness (default: the first
            ``reset(seed=...)``).
        max_steps: step limit (truncation) of this instance; default: the class attribute
            ``max_episode_steps``. (``gymnasium.make(id, max_episode_steps=N)`` instead wraps
            the env in gymnasium's ``TimeLimit``, which sets no ``final_status``.)
        client_factory: builds the client from ``(address, deadlines=, token=, tls_ca=)``
            instead of a direct gRPC ``RobotServerClient`` (the training program routes a real
            robot's env through its real-robot actor this way, for the safety filter and
            pause/resume).
        render_mode: None, ``"rgb_array"`` or ``"human"`` (see the module docstring).
        render_config: frame size and camera (default ``RenderConfig()``: 640 x 480, the
            robot family's default camera).
    """

    metadata: ClassVar[dict[str, Any]] = {"render_modes": ["rgb_array", "human"], "render_fps": 10}
    max_episode_steps: int = 500
    limit_status: ClassVar[str] = MAX_STEPS
    """``final_status`` when the step limit ends an episode."""
    needs_arguments: ClassVar[bool] = False
    """Refuse a server that does not answer GetArguments (a task whose semantics robo-gym's
    servers cannot give, so taking one on trust would silently run another task)."""

    def __init__(
        self,
        *,
        real_robot: bool = False,
        rs_address: str | None = None,
        provider: ServerProvider | None = None,
        token: str | None = None,
        tls_ca: str | os.PathLike | bytes | None = None,
        deadlines: Deadlines | None = None,
        server_seed: int | None = None,
        max_steps: int | None = None,
        client_factory: Callable[..., Any] | None = None,
        render_mode: str | None = None,
        render_config: RenderConfig | None = None,
    ) -> None:
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ConfigError(
                f"{type(self).__name__}: render_mode {render_mode!r} is not one of "
                f"{self.metadata['render_modes']} (or None)"
            )
        if render_mode == "human":
            check_display(type(self).__name__)
        self.render_mode = render_mode
        self.render_config = render_config or RenderConfig()
        self._window = (
            HumanWindow(type(self).__name__, self.metadata["render_fps"])
            if render_mode == "human"
            else None
        )
        self._last_msg: pb.State | None = None
        if real_robot and not rs_address:
            raise ConfigError(
                f"{type(self).__name__}: the Real variant needs rs_address='host:port' of a "
                "running robot server (it never starts one)"
            )
        if real_robot and provider is not None:
            raise ConfigError(f"{type(self).__name__}: a Real env takes rs_address, not provider")
        self.real_robot = real_robot
        self.client_factory = client_factory
        if rs_address:
            provider = StaticServerProvider(rs_address, token)
        self.provider: ServerProvider = provider or default_provider()
        self.token = token
        self.tls_ca = read_ca(tls_ca, "tls_ca")  # a bad file is refused here, not at reset
        if deadlines is None:
            # Our own simulations (embedded or supervised) answer in milliseconds: short
            # deadlines turn a hung server into a restart quickly. A fixed address may be a
            # real robot or robo-gym's ROS server, which get robo-gym's own deadlines.
            ours = not self.real_robot and not isinstance(self.provider, StaticServerProvider)
            deadlines = Deadlines.fast() if ours else Deadlines()
        self.deadlines = deadlines
        self.server_seed = server_seed
        if max_steps is not None:
            self.max_episode_steps = int(max_steps)
        self.elapsed_steps = 0
        self.lease: ServerLease | None = None
        self.client: RobotServerClient | None = None
        self.restarts = 0
        self._last_obs: np.ndarray | None = None

    # -- what a task defines ---------------------------------------------------------------
    @abstractmethod
    def server_spec(self) -> tuple[str, str | None, dict[str, str]]:
        """``(robot, scene, options)`` a provider needs to start this task's server."""

    @abstractmethod
    def _reset_server(self, client: RobotServerClient, options: Mapping[str, Any]) -> pb.State:
        """Sample the episode (with ``self.np_random``), SetState, and return the first state."""

    @abstractmethod
    def _send(self, client: RobotServerClient, action: np.ndarray) -> pb.State:
        """Send one (clipped, finite) action and return the state after it."""

    @abstractmethod
    def _to_obs(self, msg: pb.State) -> np.ndarray:
        """Observation (float32) from a state message; may raise InvalidStateError."""

    @abstractmethod
    def _draw(self, msg: pb.State, cfg: RenderConfig) -> np.ndarray:
        """A ``uint8`` H x W x 3 frame of the scene in ``msg`` (``envs/render``)."""

    @abstractmethod
    def _evaluate(
        self, msg: pb.State, obs: np.ndarray, action: np.ndarray
    ) -> tuple[float, str | None, StepInfo]:
        """``(reward, terminal status or None, info)`` of one step."""

    # -- gymnasium API ---------------------------------------------------------------------
    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, StepInfo]:
        super().reset(seed=seed)
        if self.server_seed is None and seed is not None:
            self.server_seed = seed
        attempts = 1 if self.real_robot else 2
        for attempt in range(attempts):
            try:
                msg = self._reset_server(self._connected(), options or {})
                break
            except RobotServerError as exc:
                if attempt + 1 == attempts:
                    raise
                self._replace_server(exc.cause)
        self.elapsed_steps = 0
        obs = self.observe(msg)
        self._last_obs = obs
        self._shown(msg, reset=True)
        return obs, {"server": self.client.address if self.client else ""}

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, StepInfo]:
        if self._last_obs is None or self.client is None:
            raise gym.error.ResetNeeded(f"{type(self).__name__}: call reset() before step()")
        assert isinstance(self.action_space, gym.spaces.Box)
        vec = check_action(action, self.action_space.shape[0])
        vec = np.clip(vec, self.action_space.low, self.action_space.high)
        try:
            msg = self._send(self.client, vec)
        except RobotServerError as exc:
            if self.real_robot:
                raise
            return self._end_after_fault(exc)
        obs = self.observe(msg)
        self.elapsed_steps += 1
        reward, status, info = self._evaluate(msg, obs, vec)
        terminated = status is not None
        truncated = not terminated and self.elapsed_steps >= self.max_episode_steps
        if truncated:
            status = self.limit_status
        if status is not None:
            info["final_status"] = status
        self._last_obs = obs
        self._shown(msg)
        return obs, float(reward), terminated, truncated, info

    def render(self) -> np.ndarray | None:
        """The current frame (``rgb_array``); ``human`` shows it (frames follow every step)."""
        if self.render_mode is None:
            gym.logger.warn(
                f"{type(self).__name__}.render() without a render_mode: pass "
                "render_mode='rgb_array' (or 'human') to gymnasium.make"
            )
            return None
        if self._last_msg is None:
            raise gym.error.ResetNeeded(f"{type(self).__name__}: call reset() before render()")
        frame = self._draw(self._last_msg, self.render_config)
        if self._window is not None:
            self._window.show(frame)
            return None
        return frame

    def _shown(self, msg: pb.State, reset: bool = False) -> None:
        """Keep the state a frame is drawn from; a human window is redrawn right away."""
        self._last_msg = msg  # a reference: position() and render() read it
        if self.render_mode is None:  # not rendering costs nothing more
            return
        self._on_state(msg, reset)
        if self._window is not None:
            self.render()

    def position(self) -> np.ndarray | None:
        """Where the robot is in the last state (MiR100: x, y; UR: tool0 x, y, z), for paths
        drawn over a map; None before the first reset or for a task without one."""
        return None if self._last_msg is None else self._position(self._last_msg)

    def _position(self, msg: pb.State) -> np.ndarray | None:
        return None

    def _on_state(self, msg: pb.State, reset: bool) -> None:
        """Hook for what a task keeps for its frames (e.g. the path so far); called only when
        rendering."""

    def close(self) -> None:
        if self._window is not None:
            self._window.close()
        self._disconnect()
        super().close()

    # -- helpers for tasks -----------------------------------------------------------------
    def observe(self, msg: pb.State) -> np.ndarray:
        """``_to_obs`` plus robo-gym's space check (InvalidStateError naming the bad value)."""
        obs = self._to_obs(msg)
        space = self.observation_space
        assert isinstance(space, gym.spaces.Box)
        if obs.shape != space.shape:
            raise InvalidStateError(
                f"observation has shape {obs.shape}, expected {space.shape} ({self._where()})"
            )
        bad = np.flatnonzero(~((obs >= space.low) & (obs <= space.high)))
        if bad.size:
            i = int(bad[0])
            low, high = space.low[i], space.high[i]
            raise InvalidStateError(
                f"observation[{i}] = {obs[i]:.6g} outside [{low:.6g}, {high:.6g}] "
                f"({bad.size} bad values; state from {self._where()})"
            )
        return obs

    def _where(self) -> str:
        return f"robot server {self.client.address}" if self.client else "no server"

    # -- server management -----------------------------------------------------------------
    def _connected(self) -> RobotServerClient:
        if self.client is None:
            robot, scene, options = self.server_spec()
            self.lease = self.provider.acquire(robot, scene, options, self.server_seed)
            connect = getattr(self.lease, "connect", None)
            if connect is not None and self.client_factory is None:  # in-process: no wire
                self.client = connect(self.deadlines)
            else:
                token = getattr(self.lease, "token", None) or self.token
                factory = self.client_factory or RobotServerClient
                self.client = factory(
                    self.lease.address, deadlines=self.deadlines, token=token, tls_ca=self.tls_ca
                )
            self._check_arguments(self.client)
        return self.client

    def _check_arguments(self, client: Any) -> None:
        """Where the server answers GetArguments, refuse one launched for another task: its
        action rate, rs_mode or action_mode differ from what ``server_spec()`` asks for (a
        real robot's server is started by hand; the real-robot actor's client relays the
        call). Servers without it (robo-gym 2.0.x's, which answer UNIMPLEMENTED) and clients
        without it are taken on trust, unless the task ``needs_arguments``.
        """
        ask = getattr(client, "get_arguments", None)
        args = ask() if ask is not None else None
        if args is None:
            if ask is not None and self.needs_arguments:
                address = getattr(self.client, "address", "?")
                raise ConfigError(
                    f"{type(self).__name__}: the robot server at {address} does not answer "
                    f"GetArguments, so nothing says it runs {self._mode_needed()}; this task "
                    "needs a server that reports it (robogym-ray serve does)"
                )
            return
        options = self.server_spec()[2]
        wrong: dict[str, tuple[str, str]] = {}  # name: (what the server runs, what is needed)
        rate = options.get("action_cycle_rate")
        if rate is not None and not math.isclose(args.action_cycle_rate, float(rate), rel_tol=1e-4):
            wrong["action_cycle_rate"] = (f"{args.action_cycle_rate:g}", rate)
        for name in ("rs_mode", "action_mode"):
            want, got = options.get(name), getattr(args, name)
            if want is not None and got and got != want:
                wrong[name] = (got, want)
        if wrong:  # all of them at once: a restart that fixes one would meet the next
            address = getattr(self.client, "address", "?")
            runs = " and ".join(f"{name} {got}" for name, (got, _) in wrong.items())
            needs = " and ".join(want for _, want in wrong.values())
            raise ConfigError(
                f"{type(self).__name__}: the robot server at {address} runs {runs}, this task "
                f"needs {needs} ({restart_hint({k: want for k, (_, want) in wrong.items()})})"
            )

    def _mode_needed(self) -> str:
        options = self.server_spec()[2]
        return " and ".join(f"{k} {options[k]}" for k in ("action_mode", "rs_mode") if k in options)

    def _disconnect(self) -> None:
        if self.client is not None:
            self.client.close()
            self.client = None
        if self.lease is not None:
            lease, self.lease = self.lease, None
            lease.release()

    def _replace_server(self, cause: str) -> None:
        if self.lease is not None:
            self.lease.report_fault(cause)
        self._disconnect()
        self.restarts += 1
        self._connected()

    def _end_after_fault(
        self, exc: RobotServerError
    ) -> tuple[np.ndarray, float, bool, bool, StepInfo]:
        info: StepInfo = {"final_status": SERVER_RESTARTED, "error": str(exc), "fault": exc.cause}
        try:
            self._replace_server(exc.cause)
        except RobotServerError as again:  # next reset() tries again and raises if it must
            info["restart_error"] = str(again)
            self._disconnect()
        obs = self._last_obs
        assert obs is not None
        self._last_obs = None  # the episode is over: step() needs a reset first
        return obs.copy(), 0.0, False, True, info  # a copy: the caller may keep the last one


def polar_2d(dx: float, dy: float, yaw: float) -> tuple[float, float]:
    """Distance and bearing (wrapped to [-pi, pi)) of ``(dx, dy)`` seen from heading ``yaw``."""
    angle = np.arctan2(dy, dx) - yaw
    return float(np.hypot(dx, dy)), float((angle + np.pi) % (2 * np.pi) - np.pi)
