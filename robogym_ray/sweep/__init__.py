"""Sweeps: trainings of one base config over a search space, as concurrent Ray Tune trials.

``robogym-ray sweep`` (``command.py``) plans and checks a sweep without Ray (``plan.py``,
``space.py``), then runs it on Tune (``tuner.py``), each trial a ``trial.TrainingTrial`` in a
placement group of its own (``bundles.py``: one bundle per actor of the run's actor table);
``robogym-ray sweep summary NAME`` reads its folder (``report.py``).
Nothing here is imported by ``import robogym_ray``: Tune loads only when a sweep runs.
"""
