"""A committed checkpoint still evaluates to its committed numbers.

``docs/results/navigation-sectors-11min/learner.pt`` is the policy part (online and averaged
nets) of a navigation checkpoint written before the package was restructured, and
``evaluation.json`` beside it is what ``robogym-ray evaluate`` made of it then (300 episodes,
seeds 1000+). Re-running its first episodes through the current code must give the same episodes:
same outcome, same length, same target, and the same return up to the floating point of the
CPU it runs on.

What "the same return" can mean across CPUs: numpy's and torch's kernels take SIMD paths of
the CPU they find, so the policy's actions may differ in their last bits from those of the
machine that wrote the file. An episode that reaches its target (here within 122-168 steps)
keeps those bits where they were: its return agrees to ~1e-8 (seen on two CPUs). An episode
that drives all 500 steps without reaching anything feeds them back through 500 steps of
physics: on one Xeon its return came out 0.8 % away (35.92 against 35.63, the same outcome
and length), within 1e-5 where it was written. So: 1e-5 for an episode that terminated,
2 % for one that ran out of time.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from robogym_ray.evaluation import EvaluationConfig, evaluate

RUN = Path(__file__).resolve().parents[2] / "docs" / "results" / "navigation-sectors-11min"
EPISODES = 6


def test_a_committed_checkpoint_evaluates_to_its_committed_episodes() -> None:
    committed = json.loads((RUN / "evaluation.json").read_text())
    result = evaluate(
        RUN / "learner.pt",
        EvaluationConfig(env_id=committed["env_id"], episodes=EPISODES, seed=1000),
    )
    assert result.env_id == committed["env_id"]
    assert "#policy_average" in result.policy  # the averaged policy, as the evaluation used
    for now, then in zip(result.episodes, committed["episodes"][:EPISODES], strict=True):
        assert (now.seed, now.final_status, now.length) == (
            then["seed"], then["final_status"], then["length"],
        )  # fmt: skip
        ran_out = then["final_status"] == "max_steps_exceeded"
        assert now.ret == pytest.approx(then["ret"], rel=0.02 if ran_out else 1e-5)
        assert now.target == pytest.approx(then["target"])
