"""robogym-ray: distributed deep RL on real and simulated industrial robots (Ray + PyBullet).

``robogym_ray.train(config, **settings) -> summary`` runs one training, as ``robogym-ray train``
does (``training/api.py``); it is imported on first use, so ``import robogym_ray`` stays cheap.
"""

from typing import Any

__version__ = "0.1.0"

import robogym_ray.envs  # noqa: E402,F401 - registers the RoboGymRay/* gymnasium ids (cheap)

_LAZY = {"train": "robogym_ray.training.api", "settings": "robogym_ray.training.api"}


def __getattr__(name: str) -> Any:
    """``robogym_ray.train`` and ``robogym_ray.settings``, imported when first asked for
    (they import Ray and torch)."""
    if name in _LAZY:
        import importlib

        return getattr(importlib.import_module(_LAZY[name]), name)
    raise AttributeError(f"module 'robogym_ray' has no attribute {name!r}")
