"""Success rates with 95 % intervals, and two policies compared episode by episode.

    # one policy over 300 episodes (two evaluations with different seeds)
    python experiments/compare.py docs/results/navigation-average-256-100min/sim \
        docs/results/navigation-average-256-100min/sim-1100
    # two policies on the same seeds: episodes only one of them solves, exact McNemar p
    python experiments/compare.py docs/results/navigation-average-256-100min/sim{,-1100} \
        --vs docs/results/navigation-average-100min/sim{,-1100}
    # several policies: which episodes most of them fail, against independent failures
    python experiments/compare.py --policy docs/results/navigation-average-100min/sim{,-1100} \
        --policy docs/results/navigation-average-256-100min/sim{,-1100} \
        --policy docs/results/navigation-average-decay-100min/sim{,-1100}

Each argument is an evaluation.json or a folder holding one (``robogym-ray evaluate --out``).
The logic is ``robogym_ray.comparison``.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Sequence

from robogym_ray.comparison import load_outcomes, pair, shared_failures
from robogym_ray.errors import ConfigError


def _shared_failures(args: argparse.Namespace) -> dict:
    shared = shared_failures([load_outcomes(paths) for paths in args.policy])
    print(shared.markdown(args.at_least))
    return {
        "policies": [p.label for p in shared.policies],
        "rates": [p.rate for p in shared.policies],
        "failed_by_k": shared.histogram(),
        "expected_if_independent": shared.expected_if_independent(),
        "failed_by": {str(s): list(who) for s, who in shared.failed_by.items()},
    }


def _one_or_paired(args: argparse.Namespace) -> dict:
    a = load_outcomes(args.a, args.label_a)
    if not args.vs:
        print(a.summary())
        return {"a": a.label, "episodes": len(a.success), "rate": a.rate}
    paired = pair(a, load_outcomes(args.vs, args.label_b))
    print(paired.markdown())
    return {
        "a": a.label, "b": paired.b.label, "rate_a": a.rate, "rate_b": paired.b.rate,
        "both": paired.both, "only_a": paired.only_a, "only_b": paired.only_b,
        "neither": paired.neither, "p_value": paired.p_value,
    }  # fmt: skip


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("a", nargs="*", help="Evaluations of policy A (merged by seed).")
    parser.add_argument("--vs", nargs="+", default=[], help="Evaluations of policy B.")
    parser.add_argument(
        "--policy",
        nargs="+",
        action="append",
        default=[],
        help="Evaluations of one policy; repeat for each (at least 2, instead of A and --vs): "
        "lists the episodes several of them fail.",
    )
    parser.add_argument(
        "--at-least", type=int, default=2, help="With --policy: list episodes failed by this many."
    )
    parser.add_argument("--label-a", default="A", help="Name of policy A in the report.")
    parser.add_argument("--label-b", default="B", help="Name of policy B in the report.")
    parser.add_argument("--json", help="Also write the numbers to this JSON file.")
    args = parser.parse_args(argv)
    if bool(args.policy) == bool(args.a) or (args.policy and args.vs):
        parser.error("give policy A (and optionally --vs B), or --policy twice or more")
    try:
        record = _shared_failures(args) if args.policy else _one_or_paired(args)
    except ConfigError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    if args.json:
        with open(args.json, "w") as f:
            json.dump(record, f, indent=2)
    return 0


if __name__ == "__main__":
    sys.exit(main())
