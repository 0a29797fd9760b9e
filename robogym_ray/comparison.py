"""Success rates with confidence intervals, and two policies compared episode by episode.

Evaluations seed each episode (``robogym-ray evaluate --seed``), so two policies evaluated on
the same seeds met the same start and goal: their difference is best read from the episodes
where exactly one of them succeeded (an exact McNemar test), not from two independent rates.
``experiments/compare.py`` is the command line; ``docs/results.md`` quotes its output.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path

from robogym_ray.errors import ConfigError


def wilson_interval(successes: int, n: int, z: float = 1.96) -> tuple[float, float]:
    """Wilson score interval of a success rate (95 % by default); (0, 1) when n is 0."""
    if not 0 <= successes <= n:
        raise ValueError(f"successes = {successes} is not in [0, n = {n}]")
    if n == 0:
        return 0.0, 1.0
    p = successes / n
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
    return max(0.0, centre - half), min(1.0, centre + half)


def mcnemar_exact(only_a: int, only_b: int) -> float:
    """Two-sided exact McNemar p-value: the discordant pairs against a fair coin."""
    if only_a < 0 or only_b < 0:
        raise ValueError(f"counts must be >= 0, got {only_a} and {only_b}")
    n = only_a + only_b
    if n == 0:
        return 1.0
    tail = sum(math.comb(n, i) for i in range(min(only_a, only_b) + 1)) / 2**n
    return min(1.0, 2 * tail)


@dataclass(frozen=True)
class Outcomes:
    """Per-seed success of one policy, read from one or more evaluation.json files."""

    label: str
    env_id: str
    success: dict[int, bool]

    @property
    def rate(self) -> float:
        return sum(self.success.values()) / max(1, len(self.success))

    def summary(self) -> str:
        k, n = sum(self.success.values()), len(self.success)
        lo, hi = wilson_interval(k, n)
        ci = f"95 % CI {100 * lo:.1f}-{100 * hi:.1f}"
        return f"{self.label}: {k}/{n} = {100 * self.rate:.1f} % ({ci})"


def load_outcomes(paths: list[str | Path], label: str | None = None) -> Outcomes:
    """Merge evaluation.json files (or folders holding one); a seed seen twice is an error."""
    if not paths:
        raise ConfigError("no evaluation given")
    success: dict[int, bool] = {}
    env_ids = set()
    for raw in paths:
        path = Path(raw) / "evaluation.json" if Path(raw).is_dir() else Path(raw)
        try:
            data = json.loads(path.read_text())
            episodes, env_id = data["episodes"], data["env_id"]
            pairs = [(int(ep["seed"]), ep["final_status"] == "success") for ep in episodes]
        except (OSError, ValueError, KeyError, TypeError) as exc:
            raise ConfigError(f"{path}: not a readable evaluation.json ({exc!r})") from None
        env_ids.add(env_id)
        for seed, ok in pairs:
            if seed in success:
                raise ConfigError(f"{path}: episode seed {seed} appears twice on one side")
            success[seed] = ok
    if len(env_ids) > 1:
        raise ConfigError(f"{label or paths}: evaluations of different tasks {sorted(env_ids)}")
    return Outcomes(label or " + ".join(map(str, paths)), env_ids.pop(), success)


@dataclass(frozen=True)
class Paired:
    """Two policies on the same seeds."""

    a: Outcomes
    b: Outcomes
    both: int
    only_a: int
    only_b: int
    neither: int

    @property
    def p_value(self) -> float:
        return mcnemar_exact(self.only_a, self.only_b)

    def markdown(self) -> str:
        n = self.both + self.only_a + self.only_b + self.neither
        return "\n".join(
            [
                f"- {self.a.summary()}",
                f"- {self.b.summary()}",
                "",
                "| episodes | both succeed | only A | only B | neither | exact McNemar p |",
                "|---|---|---|---|---|---|",
                f"| {n} | {self.both} | {self.only_a} | {self.only_b} | {self.neither} "
                f"| {self.p_value:.3g} |",
            ]
        )


def pair(a: Outcomes, b: Outcomes) -> Paired:
    """Match episodes by seed; both sides must hold the same seeds of the same task."""
    if a.env_id != b.env_id:
        raise ConfigError(f"A is {a.env_id}, B is {b.env_id}: not the same task")
    if set(a.success) != set(b.success):
        missing = sorted(set(a.success) ^ set(b.success))
        raise ConfigError(f"A and B hold different seeds, e.g. {missing[:5]} on one side only")
    counts = [0, 0, 0, 0]
    for seed, ok_a in a.success.items():
        counts[(not ok_a) * 2 + (not b.success[seed])] += 1
    return Paired(a, b, *counts)
