"""Frames of an env's scene, drawn on the client from the robot state the env receives.

Why on the client ("digital twin") and not a server-side camera: the state message is all a
client ever has of a real robot, an emulated one or one of robo-gym's ROS servers, so drawing
from it renders every variant alike, needs no PyBullet client of the server, and costs nothing
on the robot side. A frame is drawn with Pillow (headless, ~1-5 ms at 640x480, see
``benchmarks/render.py``); ``human`` mode shows the same frames in a pygame window.
"""

from robogym_ray.envs.render.canvas import RenderConfig, TopDownCamera, ViewCamera
from robogym_ray.envs.render.window import HumanWindow, check_display

__all__ = ["HumanWindow", "RenderConfig", "TopDownCamera", "ViewCamera", "check_display"]
