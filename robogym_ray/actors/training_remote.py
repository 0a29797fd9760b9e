"""The Ray edge of the training program: plain classes wrapped with ``ray.remote`` here only."""

from __future__ import annotations

import logging
import os
from typing import Any

import ray

from robogym_ray.actors.evaluator import Evaluator
from robogym_ray.actors.learner_service import LearnerService
from robogym_ray.actors.rollout import RolloutWorker
from robogym_ray.actors.train_config import TrainConfig

log = logging.getLogger(__name__)


class _Rollout(RolloutWorker):
    def set_weights(self, weights_and_version: tuple[dict, int]) -> None:  # type: ignore[override]
        weights, version = weights_and_version
        super().set_weights(weights, version)

    def pid(self) -> int:
        return os.getpid()


class _Evaluator(Evaluator):
    def evaluate(self, weights_and_version: tuple[dict, int], episodes: int = 1) -> dict:  # type: ignore[override]
        weights, version = weights_and_version
        return super().evaluate(weights, version, episodes)


RolloutActor = ray.remote(_Rollout)
LearnerActor = ray.remote(LearnerService)
EvaluatorActor = ray.remote(_Evaluator)


def ensure_ray(cfg: TrainConfig) -> bool:
    """Join ``cfg.address`` or start an embedded local Ray; True if this call started it."""
    if ray.is_initialized():
        return False
    if cfg.address:
        ray.init(address=cfg.address, log_to_driver=False)
    else:
        ray.init(num_cpus=cfg.num_cpus, include_dashboard=False, log_to_driver=False)
    return True


def learner_gpus(cfg: TrainConfig) -> float:
    if cfg.learner_gpus >= 0:
        return cfg.learner_gpus
    return 1.0 if ray.cluster_resources().get("GPU", 0) >= 1 else 0.0


# -- supervisor hooks (robot servers for Sim envs) --------------------------------------------
def start_supervisor(cfg: TrainConfig, env_id: str) -> Any:
    """The supervisor actor for RoboGymRay Sim tasks, None for other envs."""
    if not env_id.startswith("RoboGymRay/"):
        return None
    from robogym_ray.actors import supervision

    return supervision.start_for_training(cfg)


def env_kwargs_for(supervisor: Any, env_id: str, index: int, probe: bool = False) -> dict:
    if supervisor is None or probe:
        return {}
    from robogym_ray.actors import supervision

    return supervision.env_kwargs(supervisor, index)


def restart_counts(supervisor: Any) -> dict[str, int]:
    if supervisor is None:
        return {}
    from robogym_ray.actors import supervision

    return supervision.restart_counts(supervisor)


def stop_supervisor(supervisor: Any) -> None:
    if supervisor is not None:
        from robogym_ray.actors import supervision

        supervision.stop(supervisor)
