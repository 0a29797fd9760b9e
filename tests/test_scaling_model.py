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


def test_threads_beyond_the_cores_the_workers_leave_count_for_nothing(model):
    one = predict(model, cores=2, workers=2, batch=1024, threads=1)
    two = predict(model, cores=2, workers=2, batch=1024, threads=2)
    assert two == one
    # 16 cores, 14 workers: two cores left, so 8 threads are counted as 2.
    eight = predict(model, cores=16, workers=14, batch=1024, threads=8)
    assert eight == predict(model, cores=16, workers=14, batch=1024, threads=2)
    assert (
        eight["env_steps_per_s"]
        > predict(model, cores=16, workers=14, batch=1024, threads=1)["env_steps_per_s"]
    )


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
