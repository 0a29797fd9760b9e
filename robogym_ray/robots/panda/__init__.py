"""The Franka Emika Panda, as robo-gym 2.1.0 and its Panda robot server define it.

``model`` (published kinematics and limits, the URDF), ``controller`` (kinematic joint
positions), ``state`` (the wire layout), ``config`` (launch options) and ``robot`` (the
``SimRobot``); ``card`` is what the registry and the launch parser read.
"""
