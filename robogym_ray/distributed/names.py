"""Names shared by everything that finds an actor on Ray (no imports: cheap for any caller)."""

NAMESPACE = "robogym-ray"
"""The Ray namespace of every named actor (supervisor, learner, real robots)."""
SUPERVISOR_NAME = "robogym-supervisor"
"""The supervisor's actor name (a training run's own supervisor: ``run_supervisor_name``)."""


def run_supervisor_name(run_name: str) -> str:
    """The actor name of the supervisor a training run starts for itself."""
    return f"{SUPERVISOR_NAME}-{run_name}"
