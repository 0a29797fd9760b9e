"""Rates, intervals and paired comparisons of evaluations (robogym_ray.comparison)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from robogym_ray.comparison import (
    load_outcomes,
    mcnemar_exact,
    pair,
    shared_failures,
    wilson_interval,
)
from robogym_ray.errors import ConfigError
from tests.experiments.test_scripts import script

RESULTS = Path(__file__).resolve().parents[2] / "docs" / "results"


def test_interval_and_exact_test_match_textbook_values() -> None:
    lo, hi = wilson_interval(290, 300)
    assert (round(lo, 3), round(hi, 3)) == (0.940, 0.982)
    assert wilson_interval(0, 0) == (0.0, 1.0) and wilson_interval(10, 10)[1] == 1.0
    # Two-sided: 2 * P(X <= 3) for X ~ Binomial(13, 1/2) = 2 * 378 / 8192.
    assert mcnemar_exact(10, 3) == pytest.approx(2 * 378 / 8192)
    assert mcnemar_exact(0, 5) == pytest.approx(2 / 32) and mcnemar_exact(6, 6) == 1.0
    assert mcnemar_exact(0, 0) == 1.0
    with pytest.raises(ValueError):
        wilson_interval(5, 3)


def _evaluation(path: Path, statuses: dict[int, str], env_id: str = "Task-v0") -> Path:
    path.mkdir(parents=True)
    episodes = [{"seed": s, "final_status": st} for s, st in statuses.items()]
    (path / "evaluation.json").write_text(json.dumps({"env_id": env_id, "episodes": episodes}))
    return path


def test_pairs_by_seed_across_files_and_refuses_mismatches(tmp_path: Path) -> None:
    a1 = _evaluation(tmp_path / "a1", {1: "success", 2: "success"})
    a2 = _evaluation(tmp_path / "a2", {3: "collision", 4: "success"})
    b = _evaluation(tmp_path / "b", {4: "timeout", 3: "success", 2: "success", 1: "collision"})
    paired = pair(load_outcomes([a1, a2]), load_outcomes([b]))
    assert (paired.both, paired.only_a, paired.only_b, paired.neither) == (1, 2, 1, 0)
    assert "| 4 | 1 | 2 | 1 | 0 |" in paired.markdown()
    with pytest.raises(ConfigError, match="different seeds"):
        pair(load_outcomes([a1]), load_outcomes([b]))
    with pytest.raises(ConfigError, match="seed 1 appears twice"):
        load_outcomes([a1, a1])
    other = _evaluation(tmp_path / "other", {1: "success", 2: "success"}, env_id="Other-v0")
    with pytest.raises(ConfigError, match="not the same task"):
        pair(load_outcomes([a1]), load_outcomes([other]))
    # An observation-only variant runs the same episodes, so it pairs; another task does not.
    beams, sectors, ur = (
        f"RoboGymRay/{t}Sim-v0"
        for t in (
            "ObstacleAvoidanceMir100",
            "ObstacleAvoidanceSectorsMir100",
            "EndEffectorPositioningUR10",
        )
    )
    seeds = {1: "success", 2: "collision"}
    on_sectors = load_outcomes([_evaluation(tmp_path / "sectors", seeds, env_id=sectors)])
    paired = pair(on_sectors, load_outcomes([_evaluation(tmp_path / "beams", seeds, beams)]))
    assert (paired.both, paired.neither) == (1, 1)
    with pytest.raises(ConfigError, match="not the same task"):
        pair(on_sectors, load_outcomes([_evaluation(tmp_path / "ur", seeds, env_id=ur)]))
    (tmp_path / "broken.json").write_text("{}")
    with pytest.raises(ConfigError, match="broken.json"):
        load_outcomes([tmp_path / "broken.json"])


def test_script_reproduces_the_documented_comparison(
    tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    # docs/results-log.md: (256, 256) vs (400, 300) nets, 300 simulation episodes:
    # 284 / 6 / 6, p = 1.
    new, old = RESULTS / "navigation-average-256-100min", RESULTS / "navigation-average-100min"
    argv = [str(new / "sim"), str(new / "sim-1100"), "--vs", str(old / "sim"),
            str(old / "sim-1100"), "--json", str(tmp_path / "c.json")]  # fmt: skip
    assert script("compare").main(argv) == 0
    record = json.loads((tmp_path / "c.json").read_text())
    assert (record["both"], record["only_a"], record["only_b"]) == (284, 6, 6)
    assert record["p_value"] == 1.0 and "290/300 = 96.7 %" in capsys.readouterr().out
    assert script("compare").main([str(new / "sim"), "--vs", str(old / "sim-1100")]) == 2


def test_shared_failures_count_policies_per_episode_against_independence(tmp_path: Path) -> None:
    ok, bad = "success", "collision"
    p1 = _evaluation(tmp_path / "p1", {1: bad, 2: bad, 3: ok, 4: ok})
    p2 = _evaluation(tmp_path / "p2", {1: bad, 2: ok, 3: ok, 4: ok})
    p3 = _evaluation(tmp_path / "p3", {1: bad, 2: ok, 3: bad, 4: ok})
    shared = shared_failures([load_outcomes([p]) for p in (p1, p2, p3)])
    assert shared.failed_by == {1: (0, 1, 2), 2: (0,), 3: (2,)}
    assert shared.histogram() == [1, 2, 0, 1]
    # Failure rates 1/2, 1/4, 1/2: P(all three fail) = 1/16, P(none) = 3/16; 4 episodes.
    expected = shared.expected_if_independent()
    assert expected[3] == pytest.approx(4 / 16) and expected[0] == pytest.approx(12 / 16)
    assert sum(expected) == pytest.approx(4)
    text = shared.markdown(at_least=2)
    assert "| episodes | 1 | 2 | 0 | 1 |" in text and "- seed 1: 3 (P1, P2, P3)" in text
    assert "seed 2" not in text.split("at least 2")[1]
    with pytest.raises(ConfigError, match="at least 2 policies"):
        shared_failures([load_outcomes([p1])])
    short = _evaluation(tmp_path / "short", {1: ok, 2: ok, 3: ok})
    with pytest.raises(ConfigError, match="P1 and P3 hold different seeds"):
        shared_failures([load_outcomes([p]) for p in (p1, p2, short)])


def test_script_lists_the_episodes_every_documented_navigation_policy_fails(
    tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    # docs/results-log.md: seeds 1053 and 1237 are failed by all five 100/120-minute policies.
    runs = ["navigation-average-100min", "navigation-average-120min",
            "navigation-average-decay-100min", "navigation-average-256-100min",
            "navigation-average-256-quiet-100min"]  # fmt: skip
    argv = [a for r in runs for a in ("--policy", str(RESULTS / r / "sim"),
                                      str(RESULTS / r / "sim-1100"))]  # fmt: skip
    assert script("compare").main([*argv, "--json", str(tmp_path / "s.json")]) == 0
    record = json.loads((tmp_path / "s.json").read_text())
    assert record["failed_by_k"] == [272, 12, 9, 3, 2, 2]
    assert [s for s, who in record["failed_by"].items() if len(who) == 5] == ["1053", "1237"]
    assert "- seed 1053: 5 (P1, P2, P3, P4, P5)" in capsys.readouterr().out
    with pytest.raises(SystemExit):  # A and --policy together is a usage error
        script("compare").main([str(RESULTS / runs[0] / "sim"), *argv])
