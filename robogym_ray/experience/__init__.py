"""The experience side, without Ray: rollout workers, the greedy-episode loop, the evaluator,
exploration noise and revisited starts. ``distributed/remote.py`` makes Ray actors of them."""
