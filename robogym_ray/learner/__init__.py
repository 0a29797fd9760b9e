"""D4PG learner in plain PyTorch (no Ray): networks, distributional math, n-step, replay."""

from robogym_ray.learner.behaviour import BehaviourPolicy, to_env_action
from robogym_ray.learner.config import D4PGConfig
from robogym_ray.learner.learner import D4PGLearner
from robogym_ray.learner.nstep import NStepAccumulator, Transition, stack_transitions
from robogym_ray.learner.replay import PrioritizedReplay

__all__ = [
    "D4PGConfig",
    "D4PGLearner",
    "NStepAccumulator",
    "BehaviourPolicy",
    "PrioritizedReplay",
    "Transition",
    "stack_transitions",
    "to_env_action",
]
