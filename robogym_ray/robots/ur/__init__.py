"""Universal Robots arms (UR3 ... UR16e): geometry, robot, controller, objects, config, state
layout and cards."""
