"""Success rates with confidence intervals, and two policies compared episode by episode.

Evaluations seed each episode (``robogym-ray evaluate --seed``), so two policies evaluated on
the same seeds met the same start and goal: their difference is best read from the episodes
where exactly one of them succeeded (an exact McNemar test), not from two independent rates.
``experiments/compare.py`` is the command line; ``docs/results-log.md`` quotes its output.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path

from robogym_ray.envs.registration import episodes_of
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


def _check_same_episodes(a: Outcomes, b: Outcomes, names: tuple[str, str] = ("A", "B")) -> None:
    if episodes_of(a.env_id) != episodes_of(b.env_id):
        raise ConfigError(f"{names[0]} is {a.env_id}, {names[1]} is {b.env_id}: not the same task")
    if set(a.success) != set(b.success):
        missing = sorted(set(a.success) ^ set(b.success))
        raise ConfigError(
            f"{names[0]} and {names[1]} hold different seeds, e.g. {missing[:5]} on one side only"
        )


def pair(a: Outcomes, b: Outcomes) -> Paired:
    """Match episodes by seed; both sides must hold the same seeds of the same task."""
    _check_same_episodes(a, b)
    counts = [0, 0, 0, 0]
    for seed, ok_a in a.success.items():
        counts[(not ok_a) * 2 + (not b.success[seed])] += 1
    return Paired(a, b, *counts)


@dataclass(frozen=True)
class SharedFailures:
    """Which episodes several policies fail, against what independent failures would give.

    If each policy failed its episodes at random, the number of policies failing one episode
    would follow a Poisson binomial law of their failure rates; far more episodes failed by
    most policies than that law expects means the failures are the scenarios (hard starts and
    goals), not chance, and another run of the same recipe would likely fail them again.
    """

    policies: tuple[Outcomes, ...]
    failed_by: dict[int, tuple[int, ...]]
    """Seed -> indices of the policies that failed it (seeds failed by at least one)."""

    @property
    def episodes(self) -> int:
        return len(self.policies[0].success)

    def histogram(self) -> list[int]:
        """Entry k: episodes failed by exactly k of the policies."""
        counts = [0] * (len(self.policies) + 1)
        counts[0] = self.episodes - len(self.failed_by)
        for who in self.failed_by.values():
            counts[len(who)] += 1
        return counts

    def expected_if_independent(self) -> list[float]:
        """Entry k: episodes expected to be failed by exactly k policies failing independently."""
        dist = [1.0]
        for policy in self.policies:
            longer = [0.0] * (len(dist) + 1)
            for k, prob in enumerate(dist):
                longer[k] += prob * policy.rate  # this policy succeeds: k failures stay k
                longer[k + 1] += prob * (1.0 - policy.rate)
            dist = longer
        return [self.episodes * p for p in dist]

    def markdown(self, at_least: int = 2) -> str:
        n = len(self.policies)
        lines = [f"- P{i + 1}: {p.summary()}" for i, p in enumerate(self.policies)]
        observed, expected = self.histogram(), self.expected_if_independent()
        lines += ["", "| failed by k policies | " + " | ".join(map(str, range(n + 1))) + " |"]
        lines += ["|---|" + "---|" * (n + 1)]
        lines += ["| episodes | " + " | ".join(map(str, observed)) + " |"]
        lines += ["| if independent | " + " | ".join(f"{e:.2f}" for e in expected) + " |"]
        shared = sorted(
            (s for s, who in self.failed_by.items() if len(who) >= at_least),
            key=lambda s: (-len(self.failed_by[s]), s),
        )
        lines += ["", f"Episodes failed by at least {at_least} of {n} policies:"]
        for seed in shared:
            who = ", ".join(f"P{i + 1}" for i in self.failed_by[seed])
            lines.append(f"- seed {seed}: {len(self.failed_by[seed])} ({who})")
        if not shared:
            lines.append("- none")
        return "\n".join(lines)


def shared_failures(policies: list[Outcomes]) -> SharedFailures:
    """Episodes (by seed) each policy failed; all must hold the same seeds of the same task."""
    if len(policies) < 2:
        raise ConfigError(f"shared failures need at least 2 policies, got {len(policies)}")
    for i, other in enumerate(policies[1:], start=2):
        _check_same_episodes(policies[0], other, ("P1", f"P{i}"))
    failed_by = {
        seed: who
        for seed in sorted(policies[0].success)
        if (who := tuple(i for i, p in enumerate(policies) if not p.success[seed]))
    }
    return SharedFailures(tuple(policies), failed_by)
