"""A robot-server client that goes through a real-robot actor (safety filter, pause/resume).

A rollout worker's Real env uses it in place of a direct gRPC client, so every command to the
hardware passes the actor's safety filter and nothing reaches a paused robot. It offers the
methods of ``robogym_ray.protocol.client.RobotServerClient`` that the envs call.
"""

from __future__ import annotations

import contextlib
import os
import time
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import ray
from ray.exceptions import RayActorError, RayTaskError

from robogym_ray.distributed.local_ray import start_local_ray
from robogym_ray.distributed.names import NAMESPACE
from robogym_ray.errors import RobotServerError
from robogym_ray.protocol import robot_server_pb2 as pb


def dict_to_state(data: dict[str, Any]) -> pb.State:
    return pb.State(
        state=data.get("state", []),
        state_dict=data.get("state_dict", {}),
        float_params=data.get("float_params", {}),
        string_params=data.get("string_params", {}),
        success=True,
    )


class RealRobotClient:
    """``RobotServerClient``-compatible calls on the named real-robot actor."""

    def __init__(self, actor: Any, address: str) -> None:
        self.actor = actor
        self.address = address

    def _call(self, method: str, *args: Any) -> Any:
        try:
            return ray.get(getattr(self.actor, method).remote(*args))
        except RayTaskError as exc:
            cause = exc.as_instanceof_cause()
            if isinstance(cause, RobotServerError):
                raise cause from None
            raise RobotServerError(
                f"{method} failed: {cause}", address=self.address, cause="rpc"
            ) from None
        except RayActorError as exc:
            raise RobotServerError(
                f"real-robot actor is gone: {exc}", address=self.address, cause="connection"
            ) from None

    def get_state(self) -> pb.State:
        return dict_to_state(self._call("get_state"))

    def set_state(self, msg: pb.State) -> None:
        self._call(
            "set_state",
            list(msg.state),
            dict(msg.state_dict),
            dict(msg.float_params),
            dict(msg.string_params),
        )

    def send_action(self, action: Sequence[float] | np.ndarray) -> None:
        self._call("send_action", np.asarray(action, dtype=np.float64).tolist())

    def send_action_get_state(self, action: Sequence[float] | np.ndarray) -> pb.State:
        return dict_to_state(
            self._call("send_action_get_state", np.asarray(action, dtype=np.float64).tolist())
        )

    def get_arguments(self) -> pb.Arguments | None:
        """The server's GetArguments through the actor, so an env checks it via the actor too."""
        found = self._call("get_arguments")
        return None if found is None else pb.Arguments(**found, success=True)

    def is_paused(self) -> bool:
        return bool(ray.get(self.actor.status.remote()).get("paused", False))

    def close(self) -> None:
        """The actor outlives the env (it belongs to the run)."""


@dataclass(frozen=True)
class RealRobotClientFactory:
    """Picklable: builds a ``RealRobotClient`` on the named actor inside the worker."""

    actor_name: str
    namespace: str = NAMESPACE

    def __call__(self, address: str, **_: Any) -> RealRobotClient:
        return RealRobotClient(ray.get_actor(self.actor_name, namespace=self.namespace), address)


@contextlib.contextmanager
def real_robot_actor(
    env_id: str, address: str, token: str | None, tls_ca: bytes | None = None
) -> Iterator[Any]:
    """A real-robot actor on ``address`` (on a new local Ray if none); yields a client factory.
    ``tls_ca``: the PEM of its server's TLS CA (None: a plain channel)."""
    from robogym_ray.distributed import robot_actors  # Ray actors: only when used
    from robogym_ray.realrobot.safety import safety_for

    started = not ray.is_initialized()
    if started:
        start_local_ray(1, namespace=NAMESPACE, log_to_driver=False)
    name = f"eval-real-{os.getpid()}-{time.monotonic_ns()}"
    actor = robot_actors.start_real_robot(
        name, address, safety_for(env_id), token=token, tls_ca=tls_ca
    )
    try:
        yield RealRobotClientFactory(name, namespace=NAMESPACE)
    finally:
        ray.kill(actor)
        if started:
            ray.shutdown()
