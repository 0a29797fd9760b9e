"""A committed checkpoint still evaluates to its committed numbers.

``docs/results/navigation-sectors-11min/learner.pt`` is the policy part (online and averaged
nets) of a navigation checkpoint written before the package was restructured, and
``evaluation.json`` beside it is what ``robogym-ray evaluate`` made of it then (300 episodes,
seeds 1000+). Re-running its first episodes through today's code must give the same episodes:
same outcome, same length, same return.
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
        assert now.ret == pytest.approx(then["ret"], rel=1e-5)
        assert now.target == pytest.approx(then["target"])
