"""robogym-ray: distributed deep RL on real and simulated industrial robots (Ray + PyBullet)."""

__version__ = "0.1.0"

import robogym_ray.envs  # noqa: E402,F401 - registers the RoboGymRay/* gymnasium ids (cheap)
