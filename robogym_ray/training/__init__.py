"""The training program: its config, presets, the driver that builds the actors and runs the
loop (``run.py``), statistics, TensorBoard logging and snapshot selection."""
