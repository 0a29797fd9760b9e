"""``robogym-ray sweep summary NAME``: the sweep's ``summary.md`` (its space, metric, best trial
with its checkpoint, and one table of its trials) and one figure (the metric against wall
time, a line per trial) written beside it, read from the sweep's folder alone (its record,
Tune's ``result.json`` per trial, each run's ``summary.json``): no Ray, any machine that
reaches the storage. The figure needs matplotlib (the experiments extra); without it the
summary is still written, and the line says so. A metric that is the same in every trial
ranks nothing: then there is no best trial, and the line says which key to rank on."""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

from robogym_ray.errors import ConfigError
from robogym_ray.learner.checkpoint import RUN_CHECKPOINT
from robogym_ray.storage import RunStorage
from robogym_ray.sweep.plan import STATE, SWEEP_RECORD, read_record, sweeps_root

TABLE = "summary.md"
"""The sweep's summary: space, metric, best trial, then the table."""
FIGURE = "curves.png"
MARKS = (0.9, 0.95)
BETWEEN_WINDOWS = "between_windows"
"""Set in a trial's results between its evaluator windows (``--report-every-steps``): an eval/*
metric there repeats the last window's."""


@dataclass
class Trial:
    name: str
    settings: dict[str, Any]
    results: list[dict[str, Any]] = field(default_factory=list)
    run: dict[str, Any] = field(default_factory=dict)
    """The run's ``summary.json`` (empty while it runs, or if its driver died)."""

    def final(self, metric: str) -> float | None:
        value = self.run.get(
            metric, next((r[metric] for r in reversed(self.results) if metric in r), None)
        )
        return None if value is None else float(value)

    def best(self, metric: str, mode: str) -> float | None:
        values = [float(r[metric]) for r in self.results if metric in r]
        return (max if mode == "max" else min)(values) if values else None

    def time_to(self, rate: float) -> float | None:
        """Wall seconds (the trial's, across resumes) of its first window at ``rate``."""
        return next(
            (float(r["wall_s"]) for r in self.results if r.get("eval/success_rate", 0.0) >= rate),
            None,
        )

    def ended(self) -> str:
        if self.run.get("ended"):
            by = self.run.get("stopped_by") or self.run.get("ended_by", "")
            return f"{self.run['ended']} ({by})" if by else str(self.run["ended"])
        return "no summary (running, or its driver died)"

    def checkpoint(self) -> str:
        if self.run.get("checkpoint"):
            return str(self.run["checkpoint"])
        last = self.results[-1] if self.results else {}
        return f"{last['run']}/{RUN_CHECKPOINT}" if last.get("run") else ""


def read_trials(folder: RunStorage, searched: Sequence[str]) -> list[Trial]:
    """Every trial folder (one holding Tune's ``result.json``) of the sweep, by name."""
    trials = []
    for name in folder.folders():
        sub = folder.child(name)
        if not sub.exists("result.json"):
            continue
        lines = sub.read_bytes("result.json").decode().splitlines()
        results = [json.loads(line) for line in lines if line.strip()]
        config = results[-1].get("config", {}) if results else {}
        short = str(results[-1].get("trial_id", name)) if results else name
        trial = Trial(short, {key: _dotted(config, key) for key in searched}, results)
        run = next((r["run"] for r in reversed(results) if r.get("run")), None)
        if run and RunStorage(run).exists("summary.json"):
            trial.run = json.loads(RunStorage(run).read_bytes("summary.json"))
        trials.append(trial)
    return trials


def _dotted(config: Mapping[str, Any], key: str) -> Any:
    section, _, name = key.partition(".")
    return config.get(section, {}).get(name)


def table(trials: Sequence[Trial], metric: str, mode: str) -> str:
    """A Markdown table: a row per trial, its settings, final and best metric, time to 90 and
    95 % success, env steps/s and how it ended."""
    keys = list(trials[0].settings) if trials else []
    head = [
        "trial",
        *keys,
        f"final {metric}",
        "best",
        "t 90 % (min)",
        "t 95 % (min)",
        "env steps/s",
        "ended",
    ]
    rows = []
    for t in trials:
        rate = t.run.get("throughput/env_steps_per_s") or next(
            (
                r["throughput/env_steps_per_s"]
                for r in reversed(t.results)
                if "throughput/env_steps_per_s" in r
            ),
            None,
        )
        rows.append(
            [
                t.name,
                *(json.dumps(t.settings[k]) for k in keys),
                _num(t.final(metric)),
                _num(t.best(metric, mode)),
                *(_num(None if (s := t.time_to(m)) is None else s / 60) for m in MARKS),
                _num(rate, 0),
                t.ended(),
            ]
        )
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    return "\n".join([*lines, *("| " + " | ".join(map(str, r)) + " |" for r in rows)])


def _num(value: float | None, digits: int = 3) -> str:
    return "-" if value is None else f"{value:.{digits}f}"


def best_trial(trials: Sequence[Trial], metric: str, mode: str) -> Trial | None:
    """The trial with the best final ``metric``; None when no trial has it, or when it is the
    same in every trial (``constant``): then it ranks nothing."""
    scored = [t for t in trials if t.final(metric) is not None]
    if not scored or constant(trials, metric) is not None:
        return None
    sign = 1.0 if mode == "max" else -1.0
    return max(scored, key=lambda t: sign * (t.final(metric) or 0.0))


def constant(trials: Sequence[Trial], metric: str) -> float | None:
    """The final ``metric`` when two trials or more have it and it is the same in all (the
    success rate of a task without a success condition: 0), else None."""
    values = [v for t in trials if (v := t.final(metric)) is not None]
    return values[0] if len(values) > 1 and len(set(values)) == 1 else None


def best_line(trials: Sequence[Trial], metric: str, mode: str, again: str) -> str:
    """The summary's line on the best trial and its checkpoint, or why there is none.
    ``again``: the ``sweep summary`` command that ranks the trials on another key."""
    best = best_trial(trials, metric, mode)
    if best is not None:
        return (
            f"best trial ({metric} {mode}): {best.name}, {metric} {best.final(metric):g}, "
            f"checkpoint {best.checkpoint()}"
        )
    value = constant(trials, metric)
    if value is None:
        return f"best trial: none yet: no trial has reported {metric}"
    return (
        f"best trial: none: {metric} is {value:g} in every trial, so it ranks nothing (a task "
        f"without a success condition?); rank them on another key: {again} --metric eval/return"
    )


def curve(results: Sequence[Mapping[str, Any]], metric: str) -> list[tuple[float, float]]:
    """A trial's (wall minutes, ``metric``) points; an eval/* metric at its windows only (a
    result between them repeats the last window's value)."""
    windows_only = metric.startswith("eval/")
    return [
        (r["wall_s"] / 60, r[metric])
        for r in results
        if metric in r and "wall_s" in r and not (windows_only and r.get(BETWEEN_WINDOWS))
    ]


def figure(trials: Sequence[Trial], path: str, metric: str) -> bool:
    """``metric`` (success rate by default; the deploy reach's window-end error) against wall
    time, a line per trial; False when matplotlib is missing."""
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return False
    fig, ax = plt.subplots(figsize=(7, 4))
    for t in trials:
        if points := curve(t.results, metric):
            label = ", ".join(f"{k}={v}" for k, v in t.settings.items()) or t.name
            ax.plot(*zip(*points, strict=True), label=label)
    ax.set_xlabel("wall time (min)")
    ax.set_ylabel(f"{metric} (evaluator, last 100 episodes)")
    if metric.endswith("_rate"):
        ax.set_ylim(-0.02, 1.02)
    ax.legend(fontsize="small")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return True


def summarize(
    name: str, storage: str | None, metric: str | None = None, mode: str | None = None
) -> str:
    """Write ``summary.md`` (the space, the metric, the best trial and the table) and the figure
    into the sweep's folder; the text to print. ``metric`` and ``mode``: rank the trials on
    another key than the sweep's."""
    folder = RunStorage(sweeps_root(storage)).child(name)
    if not folder.exists(SWEEP_RECORD) and not folder.exists(STATE):
        raise ConfigError(
            f"sweep summary: no sweep in {folder.location()} (--storage names where the sweeps are)"
        )
    record = read_record(folder)
    metric = metric or record.get("metric", "eval/success_rate")
    mode = mode or record.get("mode", "max")
    trials = read_trials(folder, record.get("searched", []))
    text = table(trials, metric, mode)
    again = f"robogym-ray sweep summary {name}" + (f" --storage {storage}" if storage else "")
    best = best_line(trials, metric, mode, again)
    folder.write_bytes(TABLE, document(name, record, metric, mode, best, text), "sweep summary")
    staged = folder.staging("")
    drawn = figure(trials, str(staged / FIGURE), metric)
    if drawn:
        folder.publish(staged / FIGURE, FIGURE, "sweep figure")
    lines = [text, "", f"summary: {folder.location(TABLE)}"]
    lines.append(
        f"figure:  {folder.location(FIGURE)}"
        if drawn
        else "figure:  not drawn: matplotlib is missing (pip install -e '.[experiments]')"
    )
    return "\n".join([*lines, best])


def document(
    name: str, record: Mapping[str, Any], metric: str, mode: str, best: str, text: str
) -> bytes:
    """``summary.md``: what was searched and how, the best trial, then the table."""
    space = record.get("space") or record.get("searched") or ["(not recorded)"]
    how = f"{metric} ({mode})"
    if record.get("scheduler") == "asha":
        how += f"; ASHA stopped trials that trailed at the same {record.get('time_attr')}"
    lines = [f"# Sweep {name}", "", f"- space: {', '.join(space)}", f"- metric: {how}", f"- {best}"]
    if record.get("command"):
        lines.append(f"- command: `{' '.join(record['command'])}`")
    return "\n".join([*lines, "", text, ""]).encode()
