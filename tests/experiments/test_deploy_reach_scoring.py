"""The deploy-reach D4PG preset and the window-error scoring of experiments/deploy_reach_errors.py
(the full 100-episode scores are in docs/results.md; here: plumbing and the statistics)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from tests.experiments.conftest import save_learner
from tests.experiments.test_scripts import load_config, script


def test_the_preset_is_the_positioning_recipe_with_the_deploy_reach_support() -> None:
    from robogym_ray.training.presets import TASKS, resolve_task

    reach, ur = load_config("isaac-deploy-reach-ur10e"), load_config("positioning")
    assert reach[1] | {"v_min": ur[1]["v_min"], "v_max": ur[1]["v_max"]} == ur[1]
    preset = resolve_task(reach[0].task)
    assert preset.env_id == "RoboGymRay/IsaacDeployReachUR10eSim-v0"
    assert (reach[1]["v_min"], reach[1]["v_max"]) == (preset.d4pg["v_min"], preset.d4pg["v_max"])
    assert TASKS["isaac-deploy-reach-ur10e"] is preset


def test_median_and_90th_percentile_over_all_windows() -> None:
    summary = script("deploy_reach_errors").summarize(
        [(0.5, 5), (0.1, 1), (0.4, 4), (0.2, 2), (0.3, 3)]
    )
    assert summary["windows"] == 5
    assert summary["position_error_m"] == {"median": 0.3, "p90": pytest.approx(0.46)}
    assert summary["rotation_error_rad"] == {"median": 3.0, "p90": pytest.approx(4.6)}


@pytest.mark.parametrize("who", ["random", "hold", "checkpoint"])
def test_the_script_scores_each_window(who: str, tmp_path: Path, capsys) -> None:
    policy = [f"--{who}"]
    if who == "checkpoint":
        save_learner(tmp_path / "learner.pt", 19, 6)
        policy = [str(tmp_path / "learner.pt")]
    main = script("deploy_reach_errors").main
    # 10 steps: each episode's only window ends at the time limit.
    argv = [*policy, "--episodes", "2", "--max-steps", "10", "--out", str(tmp_path / "out")]
    assert main(argv) == 0
    printed = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    record = json.loads((tmp_path / "out" / "errors.json").read_text())
    assert printed["windows"] == 2 and len(record["per_episode"]) == 2
    errors = [w for ep in record["per_episode"] for w in ep]
    assert printed["position_error_m"]["median"] == pytest.approx(
        sorted(e[0] for e in errors)[0] / 2 + sorted(e[0] for e in errors)[1] / 2, abs=1e-4
    )
    assert all(0 < p < 3 and 0 <= r <= 3.1416 for p, r in errors)


def test_the_figure_makes_room_below_its_axes_for_each_row_of_the_legend(tmp_path: Path) -> None:
    pytest.importorskip("matplotlib")
    from matplotlib.image import imread

    committed = Path(__file__).parents[2] / "docs/results/isaac-deploy-reach-ur10e-servo"
    files = sorted(committed.glob("errors-*.json"))[:6]
    plot = script("deploy_reach_errors").plot
    heights = []
    for n in (2, 6):
        out = plot({f.stem: str(f) for f in files[:n]}, tmp_path / f"{n}.png")
        heights.append(imread(out).shape[0])
    # One legend row per two policies, 0.3 in each at 120 dpi.
    assert heights[1] - heights[0] == 2 * 36
