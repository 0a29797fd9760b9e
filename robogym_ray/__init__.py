"""robogym-ray: distributed deep RL on real and simulated industrial robots (Ray + PyBullet)."""

__version__ = "0.1.0"
