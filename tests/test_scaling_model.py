"""docs/scaling.md's cost model (benchmarks/scaling_model.py) on this machine's measured costs."""

import importlib.util
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "docs/results/scaling-2026-11-26"


@pytest.fixture(scope="module")
def model():
    spec = importlib.util.spec_from_file_location(
        "scaling_model", ROOT / "benchmarks/scaling_model.py"
    )
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def predict(model, **kw):
    costs = model.load_costs()
    return model.predict(costs, task="navigation", envs=4, samples_per_insert=32.0, **kw)


def test_a_thread_on_busy_shared_cores_costs_more_than_it_gives(model):
    # Two workers on two cores, batch 1,024: two threads made fewer env steps/s than one
    # (docs/scaling.md, 263 against 325), and the model says so from the measured contention.
    one = predict(model, cores=2, workers=2, batch=1024, threads=1)
    two = predict(model, cores=2, workers=2, batch=1024, threads=2)
    assert two["learner_steps_per_s"] < one["learner_steps_per_s"]


def test_contention_grows_with_the_rest_and_is_nothing_where_free_cores_hold_it(model):
    costs = model.load_costs()
    kept = [model.contention(costs, rest, cores=2, threads=2) for rest in (0, 0.3, 0.6, 1, 2)]
    assert kept[0] == 1.0 and kept == sorted(kept, reverse=True) and kept[-1] < 0.5
    # One thread on two cores: the other core holds up to one core of the rest.
    assert model.contention(costs, 0.9, cores=2, threads=1) == 1.0
    assert model.contention(costs, 1.5, cores=2, threads=1) < 1.0
    # The measured points come back where they were measured.
    table = costs["learner_contended"]
    for load, rate in zip(table["load"], table["rate"], strict=True):
        assert model.contention(costs, load, 2, 2) == pytest.approx(rate / table["rate"][0])


def test_threads_with_cores_of_their_own_speed_up_the_learner(model):
    one = predict(model, cores=16, workers=4, batch=1024, threads=1)
    eight = predict(model, cores=16, workers=4, batch=1024, threads=8)
    assert one["bound"] == eight["bound"] == "learner"
    assert eight["learner_steps_per_s"] > 2 * one["learner_steps_per_s"]


def test_a_gpu_learner_leaves_the_cores_to_bind(model):
    out = predict(model, cores=16, workers=14, batch=1792, gpu=True)
    assert out["bound"] == "cores"
    assert out["learner_steps_per_s"] == pytest.approx(out["env_steps_per_s"] * 32 / 1792)


def test_the_check_covers_every_committed_run(model):
    rows = model.check(sorted(RESULTS.glob("train-*.jsonl")), model.load_costs())
    assert len(rows) >= 20  # as docs/scaling.md lists them; more as runs are added
    assert all(r["runs"] >= 1 and r["measured_median"] > 0 for r in rows)


def test_a_short_run_reports_the_start_up_the_steady_state_leaves_out(model):
    steady = {"env_steps_per_s": 300.0, "learner_steps_per_s": 2.0}
    # 4,096 transitions at 1,024/s: 4 s before the learner's first step, of a 40-s run.
    run = model.over_a_run(steady, free_rate=1024.0, wall_s=40.0, first_step=4096)
    assert run["env_steps_per_s"] == pytest.approx((4096 + 300 * 36) / 40)
    assert run["learner_steps_per_s"] == pytest.approx(2.0 * 36 / 40)
    # A run over before the learner starts reports the free rate and no learner steps.
    assert model.over_a_run(steady, 1024.0, 3.0, 4096) == {
        "env_steps_per_s": 1024.0,
        "learner_steps_per_s": 0.0,
    }
