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
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

TAGS = ("train/success_rate", "eval/success_rate")
FIRST_EPISODE_TAG = "episode/return"  # written once per finished episode
STATUS_COLOURS = {"success": "tab:green", "collision": "tab:red",
                  "max_steps_exceeded": "tab:orange"}  # fmt: skip


def read_scalars(run_dir: str | Path, tags: Sequence[str] = TAGS) -> dict[str, tuple[list, list]]:
    """``{tag: (steps, values)}`` for the tags a TensorBoard run directory has."""
    from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

    acc = EventAccumulator(str(run_dir), size_guidance={"scalars": 0})  # 0 = keep all
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


def plot_success(runs: Mapping[str, Sequence[str | Path]], out: str | Path) -> Path:
    """One panel per problem: train and eval success rate (last 100 episodes) vs env steps."""
    plt = _pyplot()
    fig, axes = plt.subplots(1, len(runs), figsize=(5.5 * len(runs), 4), squeeze=False)
    for ax, (title, run_dirs) in zip(axes[0], runs.items(), strict=True):
        scalars, starts = read_stitched(run_dirs)
        for tag, style in zip(TAGS, ("-", "--"), strict=True):
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


def plot_targets(evaluation_json: str | Path, out: str | Path) -> Path:
    """UR targets of a final evaluation coloured by final status (3D and top view)."""
    plt = _pyplot()
    data = json.loads(Path(evaluation_json).read_text())
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


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    more = " (several: a run, then its --init-from continuations, in order)"
    parser.add_argument(
        "--navigation", nargs="+", help="Run directory of the navigation training" + more
    )
    parser.add_argument(
        "--positioning", nargs="+", help="Run directory of the positioning training" + more
    )
    parser.add_argument("--ur-eval", help="evaluation.json of the UR10 final evaluation.")
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
    if args.ur_eval:
        written.append(plot_targets(args.ur_eval, out / "ur_targets.png"))
    if not written:
        parser.error("nothing to plot: give --navigation, --positioning and/or --ur-eval")
    print(json.dumps([str(p) for p in written]))
    return 0


if __name__ == "__main__":
    sys.exit(main())
