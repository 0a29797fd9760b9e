"""``robogym-ray sweep``: seeds and recipes as concurrent trainings (Ray Tune trials), and
``robogym-ray sweep summary NAME``: the sweep's table and figure."""

from __future__ import annotations

import argparse
import sys

from robogym_ray.config import add_config_args, config_from_args
from robogym_ray.sweep.config import SweepConfig

HELP_GROUPS: dict[str, tuple[str, ...]] = {
    "the trainings (a base config, settings on top, a search space)": (
        "config",
        "set",
        "space",
        "seeds",
        "samples",
    ),
    "scheduling": (
        "max_concurrent",
        "scheduler",
        "metric",
        "mode",
        "time_attr",
        "grace_period",
        "reduction_factor",
        "report_every_steps",
    ),
    "placement (each trial's actors in a placement group of its own)": (
        "trial_cpus",
        "placement",
        "address",
        "num_cpus",
    ),
    "storage": ("name", "storage", "resume"),
}
"""``sweep --help``'s sections: every SweepConfig field in one."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.usage = (
        "%(prog)s [--config FILE] [--set KEY=VALUE ...] [--space KEY=SPEC ...] "
        "[options]\n       %(prog)s summary NAME [--storage STORAGE] [--metric KEY] "
        "[--mode {max,min}]"
    )
    parser.epilog = (
        "example: robogym-ray sweep --config experiments/configs/navigation.json "
        "--space d4pg.sigma=0.2,0.4 --seeds 0 1 --scheduler asha --name nav-sigma"
    )
    add_config_args(parser, SweepConfig, groups=HELP_GROUPS)
    # One line in --help: the group's metavar and help, and no help of the parser's own
    # (argparse would list the action a second time under it).
    actions = parser.add_subparsers(
        dest="sweep_action",
        title="a sweep's results",
        metavar="summary NAME",
        help="the sweep's table and figure (written into its folder)",
    )
    summary = actions.add_parser(
        "summary",
        prog="robogym-ray sweep summary",
        description="The sweep's summary.md (its space, metric, best trial with its checkpoint, "
        "and one table of the trials: settings, final and best metric, time to 90 and 95 % "
        "success, env steps/s, how each ended) and one figure (the metric against wall time) "
        "written into its folder.",
    )
    summary.add_argument("sweep_name", metavar="NAME", help="the sweep's folder name")
    summary.add_argument(
        "--storage",
        dest="summary_storage",
        metavar="STORAGE",
        default=None,
        help="where the sweeps are, as sweep --storage (default: runs)",
    )
    summary.add_argument(
        "--metric",
        dest="summary_metric",
        metavar="KEY",
        default=None,
        help="the result key trials are ranked on (default: the sweep's --metric)",
    )
    summary.add_argument(
        "--mode",
        dest="summary_mode",
        choices=("max", "min"),
        default=None,
        help="which way --metric is better (default: the sweep's --mode)",
    )


def run(args: argparse.Namespace) -> int:
    if getattr(args, "sweep_action", None) == "summary":
        from robogym_ray.sweep.report import summarize

        text = summarize(
            args.sweep_name, args.summary_storage, args.summary_metric, args.summary_mode
        )
        print(text, flush=True)
        return 0
    from robogym_ray.sweep.plan import plan_sweep

    cfg = config_from_args(SweepConfig, args)
    plan = plan_sweep(cfg)  # a bad space costs no Ray start
    if plan.finished:
        table = f"its table: robogym-ray sweep summary {plan.name} --storage {plan.root}"
        print(f"sweep {plan.folder.location()} finished, nothing to resume ({table})", flush=True)
        return 0
    from robogym_ray.sweep.report import summarize
    from robogym_ray.sweep.tuner import run_sweep

    # The command as cli.main received it (a Python caller's list, not this process's sys.argv).
    grid = run_sweep(plan, args.argv[args.argv.index("sweep") + 1 :])
    for result in grid:
        if result.error is not None:  # its one line: the trial's own error, not Tune's wrapping
            print(
                f"trial {result.path.rsplit('/', 1)[-1]}: {_last_line(result.error)}",
                file=sys.stderr,
            )
    print(summarize(plan.name, plan.root), flush=True)
    return 0


def _last_line(error: BaseException) -> str:
    lines = [line for line in str(error).splitlines() if line.strip()]
    return lines[-1] if lines else type(error).__name__
