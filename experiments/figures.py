"""The paper's figures from training runs and a final evaluation (matplotlib, PNG).

    pip install -e ".[experiments]"        # matplotlib
    python experiments/figures.py --navigation runs/paper/navigation \
        --positioning runs/paper/positioning runs/paper/positioning-cont \
        --ur-eval results/pos-sim/evaluation.json --out figures/

* ``success_rate.png``: success rate over the last 100 episodes against env steps, one panel
  per problem: the rollout workers' episodes (``train/success_rate``, with exploration noise)
  and the evaluator's greedy episodes (``eval/success_rate``), read from TensorBoard files;
  a run continued with ``--init-from`` is drawn as one curve, its continuations marked.
* ``ur_targets.png``: the UR10 final-evaluation targets (base_link, m) coloured by terminal
  status, in 3D and seen from above.
* ``mir_paths.png`` (``--mir-eval``, an ``evaluate --paths`` evaluation.json): every MiR100
  evaluation episode as a path over the lab map coloured by terminal status, and beside it the
  failed episodes one by one (or ``--mir-seeds``) with their cubes, the 0.40 m no-go circle
  around each cube centre, the start, the target and where the episode ended.
* ``curves.png`` (``--curves``, ``curve.json`` files of ``experiments/peers.py evaluate``):
  success of the same 100 greedy episodes against wall time for each saved policy of several
  runs; the runs of one method (labels ``METHOD seed N``) share a colour and are drawn thin.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from robogym_ray.storage import local_run, read_text

TAGS = ("train/success_rate", "eval/success_rate")
KIND_TAGS = ("sim/success_rate", "real/success_rate", "eval/success_rate")
"""A run with ``--real-robot``: the simulated workers', the real robot's and the evaluator's."""
FIRST_EPISODE_TAG = "episode/return"  # written once per finished episode
STATUS_COLOURS = {"success": "tab:green", "collision": "tab:red",
                  "max_steps_exceeded": "tab:orange"}  # fmt: skip
CLOSE_UPS = 4  # failed episodes drawn one by one beside the overview


def read_scalars(run_dir: str | Path, tags: Sequence[str] = TAGS) -> dict[str, tuple[list, list]]:
    """``{tag: (steps, values)}`` for the tags a TensorBoard run directory has."""
    from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

    # 0 = keep all; an object store's run is downloaded first
    acc = EventAccumulator(str(local_run(run_dir)), size_guidance={"scalars": 0})
    acc.Reload()
    have = set(acc.Tags().get("scalars", ()))
    out = {}
    for tag in tags:
        if tag in have:
            events = acc.Scalars(tag)
            out[tag] = ([e.step for e in events], [e.value for e in events])
    return out


def _pyplot() -> Any:
    import matplotlib

    matplotlib.use("Agg")  # files only: no display on a training machine
    import matplotlib.pyplot as plt

    return plt


def read_stitched(
    run_dirs: Sequence[str | Path], tags: Sequence[str] = TAGS
) -> tuple[dict[str, tuple[list, list]], list[int]]:
    """Scalars of a run and its continuations (``--init-from``) as one curve.

    Each continuation counts its env steps from 0, so it is shifted to start where the run
    before it ended. Returns the curves and the env steps at which each continuation began.
    """
    out: dict[str, tuple[list, list]] = {tag: ([], []) for tag in tags}
    offset, starts = 0, []
    for i, run_dir in enumerate(run_dirs):
        scalars = read_scalars(run_dir, [*tags, FIRST_EPISODE_TAG])
        episodes = scalars.pop(FIRST_EPISODE_TAG, ([], []))[0]
        # Older runs logged the train rates as 0 before their first episode had ended.
        first_episode = min(episodes, default=0)
        if i:
            starts.append(offset)
        last = 0
        for tag, (steps, values) in scalars.items():
            kept = [(s, v) for s, v in zip(steps, values, strict=True) if s >= first_episode]
            out[tag][0].extend(offset + s for s, _ in kept)
            out[tag][1].extend(v for _, v in kept)
            last = max([last, *steps])
        offset += last
    return {tag: curve for tag, curve in out.items() if curve[0]}, starts


def plot_success(
    runs: Mapping[str, Sequence[str | Path]], out: str | Path, tags: Sequence[str] = TAGS
) -> Path:
    """One panel per problem: the ``tags``' success rates (last 100 episodes) vs env steps (by
    default train and eval; ``KIND_TAGS``: a real robot's beside the simulated workers')."""
    plt = _pyplot()
    fig, axes = plt.subplots(1, len(runs), figsize=(5.5 * len(runs), 4), squeeze=False)
    for ax, (title, run_dirs) in zip(axes[0], runs.items(), strict=True):
        scalars, starts = read_stitched(run_dirs, tags)
        for tag, style in zip(tags, ("-", "--", ":"), strict=False):
            if tag in scalars:
                steps, values = scalars[tag]
                ax.plot(steps, values, style, label=tag.split("/")[0])
        for i, start in enumerate(starts):
            ax.axvline(start, color="gray", lw=0.8, ls=":", label="continued" if not i else None)
        ax.set(
            title=title,
            xlabel="env steps",
            ylabel="success rate (last 100 episodes)",
            ylim=(-0.02, 1.02),
        )
        ax.grid(alpha=0.3)
        ax.legend(loc="lower right")
    fig.tight_layout()
    out = Path(out)
    fig.savefig(out, dpi=120)
    plt.close(fig)
    return out


def first_reach(
    history: Sequence[Mapping[str, float]], rate: float, window: int = 100
) -> float | None:
    """Wall seconds at which the evaluator's success rate first reached ``rate`` with a full
    window of ``window`` episodes behind it (``summary.json``'s ``eval_history``, one episode
    per entry), or None. Earlier entries rate fewer episodes: one success reads as 100 %."""
    for i, entry in enumerate(history):
        if i + 1 >= window and entry["success_rate"] >= rate:
            return float(entry["wall_s"])
    return None


def plot_time_to_success(
    summaries: Mapping[str, str | Path], out: str | Path, rate: float
) -> tuple[Path, dict[str, float | None]]:
    """The evaluator's success rate against wall time for several runs' ``summary.json``
    (``eval_history``), the first full-window crossing of ``rate`` marked on each; returns
    the figure and each run's crossing in minutes."""
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(7, 4))
    reached: dict[str, float | None] = {}
    for label, path in summaries.items():
        history = json.loads(read_text(path))["eval_history"]
        minutes = [e["wall_s"] / 60 for e in history]
        (line,) = ax.plot(minutes, [e["success_rate"] for e in history], label=label, lw=1.2)
        when = first_reach(history, rate)
        reached[label] = None if when is None else round(when / 60, 1)
        if when is not None:
            ax.axvline(when / 60, color=line.get_color(), ls=":", lw=1)
    title = f"time to {rate:.0%} (dotted: first full-window crossing)"
    ylabel = "evaluator success (last 100 episodes)"
    return _save_rate_figure(plt, fig, ax, out, rate, ylabel, title), reached


def _save_rate_figure(plt: Any, fig: Any, ax: Any, out: str | Path, rate: float, ylabel: str,
                      title: str) -> Path:  # fmt: skip
    """A success-against-wall-minutes figure's frame (the target rate drawn), saved."""
    ax.axhline(rate, color="gray", lw=0.8)
    ax.set(xlabel="wall minutes", ylabel=ylabel, ylim=(-0.02, 1.02), title=title)
    ax.grid(alpha=0.3)
    ax.legend(loc="best", fontsize=8)
    fig.tight_layout()
    out = Path(out)
    fig.savefig(out, dpi=120)
    plt.close(fig)
    return out


def saved_at(point: Mapping[str, float]) -> float:
    """When a snapshot's weights were taken (wall minutes): its mark, or later when the
    program could save only at the end of a unit of work (an RLlib iteration)."""
    return float(point.get("saved_at_min", point["wall_min"]))


def first_snapshot(curve: Sequence[Mapping[str, float]], rate: float) -> float | None:
    """Wall minutes of a curve's first snapshot whose success reached ``rate``, or None."""
    return next((saved_at(c) for c in curve if c["success_rate"] >= rate), None)


def plot_curves(
    curves: Mapping[str, str | Path], out: str | Path, title: str
) -> tuple[Path, dict[str, dict[str, float | None]]]:
    """Each ``curve.json``'s success against wall minutes; returns the figure and each run's
    first snapshot at 90 % and at 95 %."""
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(7, 4))
    colours: dict[str, Any] = {}
    reached: dict[str, dict[str, float | None]] = {}
    for label, path in curves.items():
        curve = json.loads(read_text(path))
        method, seeded = label.split(" seed")[0], " seed" in label
        kwargs = {"color": colours[method]} if method in colours else {}
        (line,) = ax.plot([saved_at(c) for c in curve], [c["success_rate"] for c in curve],
                          marker=".", lw=0.9 if seeded else 1.8, **kwargs,
                          label=label if method not in colours or not seeded else None)  # fmt: skip
        if method not in colours:
            colours[method] = line.get_color()
            if seeded:
                line.set_label(method)
        reached[label] = {f"{r:.0%}": first_snapshot(curve, r) for r in (0.90, 0.95)}
    ylabel = "success, 100 greedy episodes (seeds 1000-1099)"
    return _save_rate_figure(plt, fig, ax, out, 0.95, ylabel, title), reached


def plot_targets(evaluation_json: str | Path, out: str | Path) -> Path:
    """UR targets of a final evaluation coloured by final status (3D and top view)."""
    plt = _pyplot()
    data = json.loads(read_text(evaluation_json))
    episodes = [e for e in data["episodes"] if e.get("target") and len(e["target"]) >= 3]
    fig = plt.figure(figsize=(11, 4.8))
    ax3 = fig.add_subplot(1, 2, 1, projection="3d")
    ax2 = fig.add_subplot(1, 2, 2)
    for status in sorted({e["final_status"] for e in episodes}):
        pts = [e["target"][:3] for e in episodes if e["final_status"] == status]
        xs, ys, zs = zip(*pts, strict=True)
        colour = STATUS_COLOURS.get(status, "tab:gray")
        label = f"{status} ({len(pts)})"
        ax3.scatter(xs, ys, zs, c=colour, s=14, label=label)
        ax2.scatter(xs, ys, c=colour, s=14, label=label)
    ax3.set(xlabel="x (m)", ylabel="y (m)", zlabel="z (m)", title=data.get("env_id", ""))
    ax2.set(xlabel="x (m)", ylabel="y (m)", title="top view", aspect="equal")
    ax2.grid(alpha=0.3)
    ax2.legend(loc="upper right", fontsize=8)
    fig.tight_layout()
    out = Path(out)
    fig.savefig(out, dpi=120)
    plt.close(fig)
    return out


def _lab(ax: Any) -> None:
    """The lab's walls, in the world frame, on ``ax``."""
    from matplotlib.patches import Polygon

    from robogym_ray.envs.render.mir100 import box_corners
    from robogym_ray.robots.mir100.scenes import LAB_ORIGIN, LAB_WALLS

    for _, (cx, cy), half in LAB_WALLS:
        corners = box_corners((LAB_ORIGIN[0] + cx, LAB_ORIGIN[1] + cy), half, 0.0)
        ax.add_patch(Polygon(corners, color="0.35"))
    ax.set(aspect="equal", xlim=(-3.2, 3.2), ylim=(-4.2, 4.2))
    ax.tick_params(labelsize=7)


def _episode(ax: Any, ep: Mapping[str, Any], close_up: bool) -> None:
    """One episode: its path, start and end; in a close-up also its cubes and target."""
    from matplotlib.patches import Circle, Polygon

    from robogym_ray.envs.mir100_tasks import ObstacleAvoidanceMir100
    from robogym_ray.envs.render.mir100 import SUCCESS_RADIUS, box_corners
    from robogym_ray.robots.mir100.scenes import CUBE_SIZE

    colour = STATUS_COLOURS.get(ep["final_status"], "tab:gray")
    xs, ys = zip(*ep["path"], strict=True)
    ax.plot(xs, ys, color=colour, lw=1.4 if close_up else 0.6, alpha=1.0 if close_up else 0.5)
    ax.plot(xs[0], ys[0], "o", color=colour, ms=4 if close_up else 2)
    if ep["final_status"] != "success":
        ax.plot(xs[-1], ys[-1], "x", color="k", ms=7 if close_up else 4)
    if not close_up:
        return
    clearance = ObstacleAvoidanceMir100.obstacle_clearance
    for x, y, yaw in ep.get("obstacles") or []:
        ax.add_patch(Polygon(box_corners((x, y), (CUBE_SIZE / 2,) * 2, yaw), color="tab:blue"))
        ax.add_patch(Circle((x, y), clearance, fill=False, ls="--", color="tab:blue", lw=0.8))
    if ep.get("target"):
        tx, ty = ep["target"][:2]
        ax.add_patch(Circle((tx, ty), SUCCESS_RADIUS, color="tab:green", alpha=0.4))
        ax.plot(tx, ty, "*", color="tab:green", ms=9)
    ax.set_title(f"seed {ep['seed']}: {ep['final_status']}, {ep['length']} steps", fontsize=8)


def plot_paths(
    evaluation_json: str | Path, out: str | Path, seeds: Sequence[int] | None = None
) -> Path:
    """MiR100 evaluation paths over the lab, coloured by status, and close-ups of failures."""
    plt = _pyplot()
    data = json.loads(read_text(evaluation_json))
    episodes = [e for e in data["episodes"] if e.get("path")]
    if not episodes or len(episodes[0]["path"][0]) != 2:
        raise SystemExit(f"{evaluation_json}: no MiR100 paths; run evaluate with --paths")
    wanted = set(seeds or ())
    close = [
        e for e in episodes if e["seed"] in wanted or (not seeds and e["final_status"] != "success")
    ]
    fig = plt.figure(figsize=(12, 7.5))
    grid = fig.add_gridspec(2, 4)
    overview = fig.add_subplot(grid[:, :2])
    _lab(overview)
    for ep in sorted(episodes, key=lambda e: e["final_status"] != "success"):  # failures on top
        _episode(overview, ep, close_up=False)
    from robogym_ray.envs.outcomes import counts

    found = counts(e["final_status"] for e in episodes)
    overview.set_title(
        f"{len(episodes)} episodes: " + ", ".join(f"{n} {c}" for c, n in found.items() if n),
        fontsize=9,
    )
    fig.suptitle(f"{data.get('env_id', '')}  ({data.get('policy', '')})", fontsize=8)
    for i, ep in enumerate(close[:CLOSE_UPS]):
        ax = fig.add_subplot(grid[i // 2, 2 + i % 2])
        _lab(ax)
        _episode(ax, ep, close_up=True)
    fig.tight_layout()
    out = Path(out)
    fig.savefig(out, dpi=120)
    plt.close(fig)
    return out


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    more = " (several: a run, then its --init-from continuations, in order)"
    parser.add_argument(
        "--navigation", nargs="+", help="Run directory of the navigation training" + more
    )
    parser.add_argument(
        "--positioning", nargs="+", help="Run directory of the positioning training" + more
    )
    parser.add_argument(
        "--real-beside-sim", nargs="+", metavar="RUN",
        help="Run directory of a training with --real-robot" + more + ": the robot's success "
        "beside the simulated workers' and the evaluator's (real_beside_sim.png).",
    )  # fmt: skip
    parser.add_argument("--ur-eval", help="evaluation.json of the UR10 final evaluation.")
    parser.add_argument(
        "--mir-eval", help="evaluation.json of a MiR100 evaluation made with evaluate --paths."
    )
    parser.add_argument(
        "--mir-seeds", nargs="+", type=int,
        help=f"Episode seeds drawn one by one (default: the first {CLOSE_UPS} failures).",
    )  # fmt: skip
    parser.add_argument(
        "--time-to", nargs="+", metavar="LABEL=SUMMARY",
        help="summary.json files (LABEL=path): evaluator success against wall time.",
    )  # fmt: skip
    parser.add_argument("--rate", type=float, default=0.95, help="--time-to's target rate.")
    parser.add_argument(
        "--curves", nargs="+", metavar="LABEL=CURVE",
        help="curve.json files of experiments/peers.py evaluate (LABEL=path; 'METHOD seed N' "
        "labels of one METHOD share a colour): success against wall time.",
    )  # fmt: skip
    parser.add_argument("--title", default="", help="--curves' figure title.")
    parser.add_argument("--out", default="figures", help="Output directory (default: figures).")
    args = parser.parse_args(argv)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    runs = {
        name: path
        for name, path in (
            ("MiR100 navigation", args.navigation),
            ("UR10 positioning", args.positioning),
        )
        if path
    }
    written = []
    if runs:
        written.append(plot_success(runs, out / "success_rate.png"))
    if args.real_beside_sim:
        runs = {"a real robot beside simulated workers": args.real_beside_sim}
        written.append(plot_success(runs, out / "real_beside_sim.png", KIND_TAGS))
    if args.ur_eval:
        written.append(plot_targets(args.ur_eval, out / "ur_targets.png"))
    if args.mir_eval:
        written.append(plot_paths(args.mir_eval, out / "mir_paths.png", args.mir_seeds))
    for item in [*(args.time_to or []), *(args.curves or [])]:
        if "=" not in item:
            parser.error(f"{item!r}: expected LABEL=PATH")
    if args.time_to:
        summaries = dict(item.split("=", 1) for item in args.time_to)
        figure, reached = plot_time_to_success(summaries, out / "time_to_success.png", args.rate)
        written.append(figure)
        print(json.dumps({"minutes_to_rate": reached}))
    if args.curves:
        curves = dict(item.split("=", 1) for item in args.curves)
        figure, first = plot_curves(curves, out / "curves.png", args.title)
        written.append(figure)
        print(json.dumps({"first_snapshot_at": first}))
    if not written:
        parser.error("nothing to plot: give --navigation, --positioning, --real-beside-sim, "
                     "--ur-eval, --mir-eval, --time-to or --curves")  # fmt: skip
    print(json.dumps([str(p) for p in written]))
    return 0


if __name__ == "__main__":
    sys.exit(main())
