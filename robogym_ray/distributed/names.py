"""Names shared by everything that finds an actor on Ray (no imports: cheap for any caller)."""

NAMESPACE = "robogym-ray"
"""The Ray namespace of every named actor (supervisor, learner, real robots)."""
SUPERVISOR_NAME = "robogym-supervisor"
"""The supervisor's actor name (a training run appends its run name)."""
