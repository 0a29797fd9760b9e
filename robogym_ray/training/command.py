"""``robogym-ray train``: distributed D4PG on local Ray or a cluster."""

from __future__ import annotations

import argparse
import json
from dataclasses import fields
from typing import Any

from robogym_ray.config import FLAGS, add_config_args
from robogym_ray.envs.outcomes import WINDOW_KEYS
from robogym_ray.robots.emulation import EmulationConfig
from robogym_ray.training import ending
from robogym_ray.training.config import TrainConfig
from robogym_ray.training.settings import TrainSetup, read_sections, setup_of

HELP_GROUPS: dict[str, tuple[str, ...]] = {
    "run": ("task", "total_steps", "max_wall_s", "seed", "config", "run_name", "resume",
            "logdir", "log_every_s", "progress"),
    "workers and paths": ("workers", "envs_per_worker", "sim_path", "emulated_workers",
                          "address", "num_cpus", "worker_cpus", "learner_cpus", "server_cpus",
                          "evaluator_cpus", "learner_gpus", "batch_per_worker",
                          "learner_resource",
                          "worker_resource", "spread_workers", "evaluator_resource",
                          "server_resource"),
    "D4PG (the workers' side; the learner's settings are the config file's d4pg section)": (
        "steps_per_call", "weight_sync_steps", "random_steps", "sigma_min",
        "sigma_decay_start", "sigma_decay_steps", "sigma_final_scale", "revisit_failed",
        "revisit_pool", "revisit_max", "relabel_goals"),
    "evaluation": ("evaluator", "eval_env_id", "eval_interval_s", "final_eval_episodes",
                   "video_interval_s", "select_episodes", "policy_snapshot_every_s"),
    "faults and storage": ("storage", "init_from", "checkpoint_every", "save_replay",
                           "replay_snapshot_every_s", "worker_deadline_s"),
    "real robots": ("real_robot", "token", "tls_ca", "real_robot_wait_s"),
}  # fmt: skip
"""``train --help``'s sections: every TrainConfig field in one (a new field in none fails the
parser's build, so every CLI test; add it here)."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    # The full usage would list every flag (~50 lines) above the sections that list them.
    parser.usage = "%(prog)s [--task TASK] [--workers N] [--config FILE] [options]"
    # Only flags given on the command line override the config file.
    sections = add_config_args(parser, TrainConfig, only_given=True, groups=HELP_GROUPS)
    add_config_args(parser, EmulationConfig, prefix="emu-", only_given=True,
                    title="emulated robots (for --emulated-workers)")  # fmt: skip
    sections["run"].add_argument(
        "--json",
        action="store_true",
        help="print the run's summary as one JSON line (it is always in RUN_DIR/summary.json)",
    )


def _given(args: argparse.Namespace, cls: type) -> dict[str, Any]:
    given = {f.name: getattr(args, f.name) for f in fields(cls) if hasattr(args, f.name)}
    return {k: tuple(v) if isinstance(v, list) else v for k, v in given.items()}


def build_config(args: argparse.Namespace) -> TrainSetup:
    train, emu = _given(args, TrainConfig), _given(args, EmulationConfig)
    source = train.get("config") or "command line"
    data = read_sections(source) if train.get("config") else {}
    return setup_of(data, source, train, emu, flagged=True)


def run(args: argparse.Namespace) -> int:
    from robogym_ray.training.api import run_checked

    # As the Python entry runs it, checked before Ray starts; errors name the flags.
    summary = run_checked(build_config(args), FLAGS)
    print(json.dumps(summary) if args.json else summary_text(summary), flush=True)
    return 0


def _rates(summary: dict[str, Any], prefix: str) -> str:
    return "  ".join(
        f"{name} {100 * summary[f'{prefix}/{name}_rate']:.1f} %"
        for name in ("success", "collision", "timeout")
    )


def _spaced_note(summary: dict[str, Any], counted: int) -> str:
    """The greedy evaluation's caveat when the evaluator ran at an interval: its last episodes
    were played over a long stretch of the run, by older policies, so its figures cannot be set
    beside a back-to-back evaluator's (whose last 100 episodes are its last minutes)."""
    interval = f"{summary['eval_interval_s']:g}"
    history, total = summary.get("eval_history") or [], summary.get("eval/episodes", 0)
    span = ""
    if history and total:  # the calls that played the counted episodes are the last ones
        per_call = max(1, round(total / len(history)))
        before = len(history) - min(len(history), -(-counted // per_call))
        started = history[before - 1]["wall_s"] if before else 0.0  # after the call before
        minutes = (summary["wall_s"] - started) / 60
        span = f", these episodes over the last {minutes:.1f} min"
    caveat = "not comparable with a back-to-back evaluator's"
    return f"    (evaluator calls every {interval} s{span}: {caveat})"


def summary_text(summary: dict[str, Any]) -> str:
    """A few lines for a person: how the run ended, how it went, where its files are."""
    from robogym_ray.training.stats import run_root

    root = run_root(summary)
    whole = ending.whole_run_line(summary)  # a run in parts (--resume): all of them
    lines = [ending.first_line(summary), *([whole] if whole else [])]
    # A task with command windows ends only by time: success rates say nothing of it (100 %
    # timeout), its window-end errors (the evaluator's) are its measure.
    windows = f"eval/{WINDOW_KEYS[0]}" in summary
    if "train/success_rate" in summary and not windows:
        # Over the last 100 episodes that were not revisits (RunStats), fewer in a short run.
        counted = min(100, summary["episodes"] - summary.get("revisited_episodes", 0))
        lines.append(f"  training episodes (last {counted}): {_rates(summary, 'train')}")
    if "eval/success_rate" in summary:
        # The evaluator's rates are over its last 100 episodes (Evaluator's window).
        total = int(summary.get("eval/episodes", 0))
        last = f"last {min(100, total)} of {total}"
        measure = (
            f"window-end error median {summary[f'eval/{WINDOW_KEYS[0]}']:.4f} m, "
            f"{summary[f'eval/{WINDOW_KEYS[1]}']:.4f} rad"
            if windows
            else _rates(summary, "eval")
        )
        lines.append(f"  greedy evaluation ({last} episodes): {measure}")
        if summary.get("eval_interval_s"):
            lines.append(_spaced_note(summary, min(100, total)))
    restarts = sum(summary["restarts"].values())
    node = summary.get("storage", {}).get("node", "")
    lines += [
        f"  faults: {restarts} server restarts, {summary['dropped_steps']} dropped steps, "
        f"{summary['robot_errors']} robot errors",
        f"  files:       {root}/" + (f"  (on {node})" if node else ""),
        f"  checkpoint:  {summary['checkpoint']}",
        f"  TensorBoard: tensorboard --logdir {root}",
        f"  summary:     {root}/summary.json (or pass --json)",
    ]
    return "\n".join(lines)
