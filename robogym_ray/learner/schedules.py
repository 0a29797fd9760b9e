"""The learner's schedules: plain functions of (config, step).

A step is a number (the host-stepped loop's ``num_steps``) or a device tensor (the whole step's
counter, ``learner/whole_step.py``): the same function serves both, and with a tensor the answer
stays on its device, so a captured CUDA graph reads no host value.
"""

from __future__ import annotations

from typing import Any

import torch

from robogym_ray.learner.config import D4PGConfig


def linear_ramp(step: Any, start: int, length: int, begin: float, end: float) -> Any:
    """``begin`` until ``start``, then linearly to ``end`` over ``length`` steps, then ``end``;
    ``step`` a number, or a tensor (the whole step's counter: the answer stays on its device)."""
    if isinstance(step, torch.Tensor):
        frac = ((step - start).clamp(min=0) / max(1, length)).clamp(max=1.0)
    else:
        frac = min(1.0, max(0, step - start) / max(1, length))
    return begin + frac * (end - begin)


def importance_beta(config: D4PGConfig, step: Any) -> Any:
    """The importance exponent at learner step ``step``: from its start value to 1."""
    c = config
    return linear_ramp(step, 0, c.importance_beta_steps, c.importance_beta_start, 1)


def lr_scale(config: D4PGConfig, step: Any) -> Any:
    """Factor on the base learning rates at learner step ``step`` (the linear late decay)."""
    c = config
    if c.lr_decay_steps <= 0:
        return 1.0
    return linear_ramp(step, c.lr_decay_start, c.lr_decay_steps, 1, c.lr_final_scale)
