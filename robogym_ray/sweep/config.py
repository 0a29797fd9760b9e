"""``SweepConfig``: what ``robogym-ray sweep`` runs (the trainings' own settings are a config
file's and ``--set``'s)."""

from __future__ import annotations

from dataclasses import dataclass

from robogym_ray.config import check_ranges, check_ray_address

SCHEDULERS = ("none", "asha")
TIME_ATTRS = ("env_steps", "wall_s")
PLACEMENTS = ("PACK", "SPREAD", "STRICT_PACK", "STRICT_SPREAD")


@dataclass(frozen=True)
class SweepConfig:
    """Trainings of one base config over a search space, as Ray Tune trials."""

    config: str | None = None
    """The trainings' base config file (train's format: "train", "d4pg", "emulation",
    "extends"); its train section's storage, run name and Ray address are the sweep's."""
    set: tuple[str, ...] = ()
    """KEY=VALUE settings on top of the base, for every trial: a dotted config key
    (d4pg.sigma, train.max_wall_s; a bare field is train's) and a JSON value."""
    space: tuple[str, ...] = ()
    """KEY=SPEC searched: a grid (0.1,0.2 or a JSON list) or uniform(A,B), loguniform(A,B),
    randint(A,B), choice(X,Y,...) drawn per trial. Checked before Ray starts."""
    seeds: tuple[int, ...] = ()
    """Seeds: a grid over train.seed (every other combination once per seed)."""
    samples: int = 1
    """Times the grid is repeated; each repetition draws the random specs anew."""
    name: str | None = None
    """The sweep's folder under --storage (default: sweep- and the time); a taken name is
    refused (--resume NAME continues it)."""
    storage: str | None = None
    """Where the sweep's folder goes, as train's --storage takes it: a path (a mount every
    node shares, on a cluster) or an object store URI. Default: the base's storage, else its
    logdir (runs)."""
    resume: str | None = None
    """Continue the sweep NAME under --storage after its driver died: unfinished trials go on
    from their last checkpoint, errored ones are retried. Takes no space."""
    max_concurrent: int = 0
    """Trials running at once (0: as many as the cluster's resources hold)."""
    scheduler: str = "none"
    """none: every trial runs to its end; asha: ASHA stops the trials whose --metric trails
    the others' at the same --time-attr."""
    metric: str = "eval/success_rate"
    """The result key trials are compared on (ASHA, the best trial, the figure):
    eval/success_rate, eval/return, ...; the deploy reach's eval/window_position_error with
    --mode min (a trial reports one result per evaluator window)."""
    mode: str = "max"
    """max or min: which way --metric is better."""
    time_attr: str = "env_steps"
    """ASHA's clock: env_steps or wall_s (the trial's, across resumes)."""
    grace_period: float = 0.0
    """ASHA: no trial is stopped before this much --time-attr (0: an eighth of the trials'
    total_steps, or of max_wall_s with wall_s)."""
    report_every_steps: int = 0
    """A trial's result every this many env steps besides its evaluator windows (0: windows
    only), carrying --metric as the last window left it: ASHA then decides at its env-step
    rungs however late a trial's evaluator starts. A result is sent only once it can carry
    --metric (an eval/* metric: after the first window). Below the base's steps_per_call it
    is one result per worker call. --resume keeps the value the sweep started with."""
    reduction_factor: float = 2.0
    """ASHA: 1/this of the trials at a rung go on to the next."""
    trial_cpus: float = 0.1
    """Ray CPUs of each trial's own actor (the run's driver; bundle 0 of its placement
    group). Each actor of the run gets a bundle of its own on top (the base's --worker-cpus,
    --learner-cpus ...)."""
    placement: str = "PACK"
    """How a trial's bundles are placed over nodes (Ray's placement strategies): PACK keeps a
    trial on as few nodes as fit it; SPREAD spreads it."""
    address: str | None = None
    """Ray address: None starts a local Ray (embedded); 'auto' joins a running cluster."""
    num_cpus: float | None = None
    """CPUs of the embedded local Ray (default: all of this machine)."""

    def __post_init__(self) -> None:
        checks = [
            (self.samples >= 1, "samples", ">= 1"),
            (self.max_concurrent >= 0, "max_concurrent", ">= 0 (0 = as many as fit)"),
            (self.scheduler in SCHEDULERS, "scheduler", f"one of {', '.join(SCHEDULERS)}"),
            (bool(self.metric), "metric", "a result key, e.g. eval/success_rate"),
            (self.mode in ("max", "min"), "mode", "max or min"),
            (self.time_attr in TIME_ATTRS, "time_attr", f"one of {', '.join(TIME_ATTRS)}"),
            (self.grace_period >= 0, "grace_period", ">= 0"),
            (self.reduction_factor > 1, "reduction_factor", "> 1"),
            (self.report_every_steps >= 0, "report_every_steps", ">= 0 (0 = windows only)"),
            (self.trial_cpus > 0, "trial_cpus", "> 0"),
            (self.placement in PLACEMENTS, "placement", f"one of {', '.join(PLACEMENTS)}"),
            (self.num_cpus is None or self.num_cpus > 0, "num_cpus", "> 0 or null"),
            (self.name is None or _plain(self.name), "name", "a folder name (no / or ..)"),
            (self.resume is None or _plain(self.resume), "resume", "a sweep's folder name"),
        ]
        check_ranges(
            "SweepConfig",
            ((ok, name, getattr(self, name), expected) for ok, name, expected in checks),
        )
        if self.address is not None:
            check_ray_address(self.address, "--address")


def _plain(name: str) -> bool:
    return bool(name) and "/" not in name and name not in (".", "..")
