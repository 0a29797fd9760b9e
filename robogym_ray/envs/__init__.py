"""Gymnasium environments on robo-gym robot servers (client side of the wire protocol).

Importing this package registers the ids in ``ENV_IDS`` (cheap: no PyBullet, no torch), and
``RoboGymRayBench/Free-v0`` (``envs/free.py``: no robot, for measuring the data path).
"""

import gymnasium as gym

from robogym_ray.envs.free import FREE_ENV_ID
from robogym_ray.envs.registration import register_all

ENV_IDS: tuple[str, ...] = tuple(register_all())
if FREE_ENV_ID not in gym.registry:
    gym.register(FREE_ENV_ID, entry_point="robogym_ray.envs.free:FreeEnv")
SIM_ENV_IDS: tuple[str, ...] = tuple(i for i in ENV_IDS if i.endswith("Sim-v0"))
REAL_ENV_IDS: tuple[str, ...] = tuple(i for i in ENV_IDS if i.endswith("Rob-v0"))

__all__ = ["ENV_IDS", "REAL_ENV_IDS", "SIM_ENV_IDS"]
