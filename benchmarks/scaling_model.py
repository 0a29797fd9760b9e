"""docs/scaling.md's cost model: env and learner steps/s of a configuration, from measured costs.

    python benchmarks/scaling_model.py check MEASURED.jsonl [...]   the model against each run
        that benchmarks/scaling.py train printed (medians of the repeats), and the error;
    python benchmarks/scaling_model.py predict --cores 16 --workers 14 --batch 1792 [--gpu]
        a configuration this machine cannot run.

The model (docs/scaling.md explains each term). With ``lam = samples_per_insert / batch``
learner steps per env step, env steps/s is the smallest of

* the cores: ``cores / (env_cpu + other_cpu + lam * learner_cpu)``, where ``learner_cpu`` is
  the CPU-seconds of one learner step (its time x its threads; 0 on a GPU);
* the learner, one step at a time: ``1 / (lam * learner_s)``;
* the workers, one process each, waiting on their calls: ``workers / (env_cpu + call_s)``,
  ``call_s`` from one free-env worker's rate;
* the data path: the free env's env steps/s, where this machine measured that shape.

and learner steps/s is ``lam`` times it. Where the learner shares its cores with the workers
(fewer cores than workers + learner threads + 1), a CPU learner step takes
``1 / learner_share_when_shared`` times its time alone (measured once, on the recipe's run: 2
workers x 4 envs, batch 256), and longer still where its threads do not all find a free core:
a thread a worker displaces holds up the others at every parallel operation. That second term
(``contention``) is measured apart from any training - the learner alone beside a process that
keeps a core busy a given share of the time - and replaced the rule that counted no thread
beyond the cores the workers leave. Costs are this machine's, measured
(``scaling_costs.json``).

``predict`` gives the steady state. A run's own figures are counts over its whole wall time,
and before the learner's first step (``max(min_replay_size, batch)`` transitions) the workers
run unhindered: ``check`` compares each run with ``over_a_run``, the steady state plus that
start, for the run's length.
"""

from __future__ import annotations

import argparse
import json
import statistics
from collections import defaultdict
from pathlib import Path

import numpy as np

COSTS_FILE = Path(__file__).with_name("scaling_costs.json")
"""The measured costs the model reads (written by hand from the benchmarks' figures)."""


def load_costs(path: Path = COSTS_FILE) -> dict:
    return json.loads(path.read_text())


def learner_seconds(costs: dict, batch: int, threads: int, gpu: bool) -> float:
    """One learner step's time: measured batches interpolated linearly in the batch; more CPU
    threads than measured by Amdahl's law with the parallel share that 1 and 2 threads show."""
    if not gpu and f"learner_cpu_s_{threads}t" not in costs:
        one, two = (learner_seconds(costs, batch, h, False) for h in (1, 2))
        parallel = 2.0 * (1.0 - two / one)  # 1 / speedup(2) = (1 - p) + p / 2
        return one * ((1.0 - parallel) + parallel / threads)
    table = costs["learner_gpu_s" if gpu else f"learner_cpu_s_{threads}t"]
    points = sorted((int(b), t) for b, t in table.items())
    for (b0, t0), (b1, t1) in zip(points, points[1:], strict=False):
        if batch <= b1:
            return t0 + (t1 - t0) * (batch - b0) / (b1 - b0)
    (b0, t0), (b1, t1) = points[-2], points[-1]
    return t1 + (t1 - t0) * (batch - b1) / (b1 - b0)  # beyond the last: the last slope


def contention(costs: dict, rest_cpu: float, cores: float, threads: int) -> float:
    """How much of its speed a CPU learner with ``threads`` threads keeps where the rest of the
    run uses ``rest_cpu`` cores: 1 where the cores its threads leave hold the rest. Measured on
    two cores, the learner alone with 2 threads beside a process busy a share of one core
    (``learner_capacity.py alone --load``): its rate there over its rate with no load,
    interpolated, the ends held beyond. With other counts it is read at the same load per
    thread - the rest's CPU beyond the cores the threads leave - which no run here checked."""
    table = costs["learner_contended"]
    load = max(0.0, rest_cpu - (cores - threads)) * table["threads"] / threads
    return float(np.interp(load, table["load"], table["rate"]) / table["rate"][0])


def predict(
    costs: dict, *, task: str, cores: float, workers: int, envs: int, batch: int,
    samples_per_insert: float, threads: int = 1, gpu: bool = False,
) -> dict:  # fmt: skip
    env_cpu = costs["env_cpu_s"][task][str(envs)]
    other = costs["other_cpu_s"]
    lam = samples_per_insert / batch
    shared = not gpu and cores < workers + threads + 1
    step_alone = learner_seconds(costs, batch, threads, gpu)
    if shared:
        # Cores shared with the workers: a learner step in a run took longer than alone.
        step_alone /= costs["learner_share_when_shared"]
    # A worker waits on its calls: one free-env worker's rate gives the per-step cost of that
    # (its call round trips and its share of the driver), beyond its env's CPU.
    solo = costs["data_path_env_steps_per_s"][f"1x{envs}"]
    call_s = 1.0 / solo - costs["env_cpu_s"]["free"][str(envs)]
    learner_host = 1.0 if gpu else 0.0  # a GPU learner's host thread still holds a core

    def ceilings(step_s: float) -> dict[str, float]:
        learner_cpu = 0.0 if gpu else step_s * threads
        return {
            "cores": (cores - learner_host) / (env_cpu + other + lam * learner_cpu),
            "learner": float("inf") if lam == 0 else 1.0 / (lam * step_s),
            "workers": workers / (env_cpu + call_s),
            # Measured on this machine only (the free env's runs), for the shapes it ran.
            "data path": costs["data_path_env_steps_per_s"].get(f"{workers}x{envs}", float("inf")),
        }

    step_s = step_alone
    limits = ceilings(step_s)
    if shared:
        # A thread that a worker displaces holds up the others at every parallel operation
        # until it runs again: the busier the cores, the slower the step. The rest's CPU is its
        # cost per env step at the rate the run reaches, which the step's time sets in turn:
        # iterated to its fixed point (a slower step lowers the load, so it settles).
        for _ in range(50):
            rest_cpu = min(limits.values()) * (env_cpu + other)
            kept = contention(costs, rest_cpu, cores, threads)
            step_s = 0.5 * step_s + 0.5 * step_alone / kept
            limits = ceilings(step_s)
    bound = min(limits, key=limits.get)
    env_rate = limits[bound]
    return {
        "env_steps_per_s": env_rate, "learner_steps_per_s": lam * env_rate, "bound": bound,
        # None where nothing bounds (JSON has no infinity).
        "ceilings": {k: round(v, 1) if v != float("inf") else None for k, v in limits.items()},
    }  # fmt: skip


RECIPE = Path(__file__).resolve().parents[1] / "experiments/configs/navigation-average.json"
"""The config ``benchmarks/scaling.py train`` runs: where it says when the learner starts."""


def over_a_run(steady: dict, free_rate: float, wall_s: float, first_step: int) -> dict:
    """What a run of ``wall_s`` seconds reports (its counts over its whole wall time), where
    ``predict`` gives the steady state: the workers first collect the ``first_step``
    transitions the learner's first step waits for, at the rate they make with no learner;
    from that step on the run keeps its ratio, counted from there (the learner never pays for
    those transitions), so they stay ahead of the learner to the end."""
    start_s = first_step / free_rate
    if start_s >= wall_s:
        return {"env_steps_per_s": free_rate, "learner_steps_per_s": 0.0}
    steady_part = (wall_s - start_s) / wall_s
    return {
        "env_steps_per_s": first_step / wall_s + steady["env_steps_per_s"] * steady_part,
        "learner_steps_per_s": steady["learner_steps_per_s"] * steady_part,
    }


def check(paths: list[Path], costs: dict) -> list[dict]:
    """Each configuration's runs (the medians) against the model over a run of their length."""
    from robogym_ray.training.settings import read_sections

    min_replay = read_sections(RECIPE)["d4pg"]["min_replay_size"]
    runs: dict[tuple, list[dict]] = defaultdict(list)
    for path in paths:
        for line in path.read_text().splitlines():
            row = json.loads(line)
            if "env_steps_per_s" not in row:
                continue
            key = (row["task"], row["workers"], row["envs"], row["batch"],
                   row["samples_per_insert"], row.get("learner_threads") or 1,
                   row.get("d4pg", "{}"), 5 * round(row["wall_s"] / 5))  # fmt: skip
            runs[key].append(row)
    out = []
    for (task, workers, envs, batch, spi, threads, d4pg, wall), rows in sorted(runs.items()):
        measured = statistics.median(r["env_steps_per_s"] for r in rows)
        shape = {"task": task, "cores": costs["cores"], "workers": workers, "envs": envs,
                 "batch": batch, "threads": threads}  # fmt: skip
        steady = predict(costs, samples_per_insert=spi, **shape)
        free = predict(costs, samples_per_insert=0.0, **shape)["env_steps_per_s"]
        model = {**steady, **over_a_run(steady, free, wall, max(min_replay, batch))}
        learner = statistics.median(r["learner_steps_per_s"] for r in rows)
        out.append({
            "task": task, "workers": workers, "envs": envs, "batch": batch, "spi": spi,
            "threads": threads, "d4pg": d4pg, "wall_s": wall, "runs": len(rows),
            "steady_model": round(steady["env_steps_per_s"], 1),
            "measured_median": round(measured, 1),
            "measured_min": min(r["env_steps_per_s"] for r in rows),
            "measured_max": max(r["env_steps_per_s"] for r in rows),
            "model": round(model["env_steps_per_s"], 1), "bound": model["bound"],
            "error": round(model["env_steps_per_s"] / measured - 1, 3),
            "learner_measured": round(learner, 2),
            "learner_model": round(model["learner_steps_per_s"], 2),
            "learner_error": round(model["learner_steps_per_s"] / learner - 1, 3)
            if learner > 0 else None,
        })  # fmt: skip
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="mode", required=True)
    c = sub.add_parser("check")
    c.add_argument("measured", type=Path, nargs="+")
    p = sub.add_parser("predict")
    p.add_argument("--task", default="navigation")
    p.add_argument("--cores", type=float, required=True)
    p.add_argument("--workers", type=int, required=True)
    p.add_argument("--envs", type=int, default=4)
    p.add_argument("--batch", type=int, default=256)
    p.add_argument("--samples-per-insert", type=float, default=32.0)
    p.add_argument("--threads", type=int, default=1)
    p.add_argument("--gpu", action="store_true")
    args = parser.parse_args()
    costs = load_costs()
    if args.mode == "check":
        rows = check(args.measured, costs)
        for row in rows:
            print(json.dumps(row))
        worst = max(abs(r["error"]) for r in rows)
        learner = [abs(r["learner_error"]) for r in rows if r["learner_error"] is not None]
        print(json.dumps({"configurations": len(rows), "worst_env_error": worst,
                          "worst_learner_error": max(learner, default=None)}))  # fmt: skip
    else:
        kw = {k: v for k, v in vars(args).items() if k != "mode"}
        print(json.dumps(predict(costs, **kw)))


if __name__ == "__main__":
    main()
