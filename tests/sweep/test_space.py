"""A sweep's input, checked before Ray starts: keys, specs, every trial a space can make, and
the resource table a trial's bundles come from (no Ray here)."""

from __future__ import annotations

import pytest

from robogym_ray.cli import main
from robogym_ray.errors import ConfigError
from robogym_ray.sweep.bundles import bundles, check_fit
from robogym_ray.sweep.space import parse_axis, parse_set, parse_space
from robogym_ray.training.config import TrainConfig
from robogym_ray.training.resources import actor_need, actor_needs, total_cpus


def refused(capfd: pytest.CaptureFixture, *argv: str) -> str:
    """``robogym-ray sweep ARGV``'s one error line (exit 2), Ray never started."""
    capfd.readouterr()
    assert main(["sweep", *argv]) == 2
    err = capfd.readouterr().err.strip()
    assert len(err.splitlines()) == 1, err
    return err


def test_specs_parse_to_grids_and_draws() -> None:
    assert parse_axis("d4pg.sigma=0.1,0.2").values == (0.1, 0.2)
    assert parse_axis("d4pg.policy_hidden=[[256,256],[64]]").values == ([256, 256], [64])
    axis = parse_axis("sigma_min=uniform(0.05, 0.1)")  # a bare key is train's
    assert (axis.key, axis.kind, axis.corners()) == ("train.sigma_min", "uniform", (0.05, 0.1))
    assert parse_axis("workers=randint(1,4)").corners() == (1, 3)
    assert parse_axis('task=choice("pendulum","navigation")').values == ("pendulum", "navigation")
    assert parse_set(["d4pg.sigma=0.3", "total_steps=10"]) == {
        "d4pg": {"sigma": 0.3}, "train": {"total_steps": 10}}  # fmt: skip
    seeds = parse_space(["d4pg.sigma=0.1,0.2"], [0, 1])[-1]
    assert (seeds.key, seeds.values) == ("train.seed", (0, 1))


@pytest.mark.parametrize(
    ("item", "says"),
    [
        ("d4pg.sigmaa=0.1", "did you mean 'sigma'"),
        ("d4gp.sigma=0.1", "no section 'd4gp'"),
        ("d4pg.sigma", "expected KEY=VALUE"),
        ("d4pg.sigma=uniform(0.3,0.1)", "expected LOW < HIGH"),
        ("d4pg.sigma=loguniform(0,1)", "LOW > 0"),
        ("d4pg.sigma=normal(0,1)", "no spec 'normal'"),
        ("workers=randint(1,2.5)", "two integers"),
    ],
)
def test_a_bad_spec_is_one_line(item: str, says: str) -> None:
    with pytest.raises(ConfigError, match=says):
        parse_axis(item)


@pytest.mark.usefixtures("ray_must_not_start")
def test_bad_spaces_are_refused_before_ray_starts(
    capfd: pytest.CaptureFixture, tmp_path: object
) -> None:
    base = ["--storage", str(tmp_path), "--set", "task=pendulum", "total_steps=100"]
    err = refused(capfd, *base, "--space", "d4pg.sigma=0.2,-1")
    assert "trial d4pg.sigma=-1" in err and "sigma" in err and ">= 0" in err
    assert "did you mean 'sigma'" in refused(capfd, *base, "--space", "d4pg.sigmaa=0.1")
    err = refused(capfd, *base, "--space", "workers=64", "--num-cpus", "2")
    assert "reserves" in err and "cluster has 2" in err
    err = refused(capfd, *base, "--space", "task=choice(pendulum,nosuchtask)")
    assert "nosuchtask" in err
    err = refused(capfd, "--resume", "gone", "--storage", str(tmp_path))
    assert "no sweep" in err
    assert "drop --space" in refused(capfd, "--resume", "x", "--space", "d4pg.sigma=0.1")
    err = refused(capfd, *base, "--scheduler", "asha", "--time-attr", "wall_s")
    assert "max_wall_s" in err
    # A time alone lifts a trial's step total: ASHA counting env steps has no budget then.
    timed = ["--storage", str(tmp_path), "--set", "task=pendulum", "max_wall_s=60"]
    err = refused(capfd, *timed, "--scheduler", "asha")
    assert "--time-attr env_steps: every trial needs train.total_steps" in err


def test_a_trials_bundles_hold_its_actors_one_each() -> None:
    cfg = TrainConfig(workers=3, learner_cpus=0.5, worker_cpus=0.25, learner_resource="gpu_node")
    needs = actor_needs(cfg, learner_gpus=1.0)
    made = bundles(needs, {"CPU": 0.1})
    assert made[0] == {"CPU": 0.1}
    assert {"CPU": 0.5, "gpu_node": 0.01, "GPU": 1.0} in made
    assert len(made) == 1 + 1 + 3 + 1 + 1  # own, learner, workers, evaluator, supervisor
    # Counted by hand: learner 0.5, three workers at 0.25, evaluator 0.1, supervisor 0.05.
    assert sum(b["CPU"] for b in made[1:]) == pytest.approx(0.5 + 3 * 0.25 + 0.1 + 0.05)
    assert total_cpus(needs) == pytest.approx(1.4)
    check_fit(needs, made[1:])
    with pytest.raises(ConfigError, match="no room for the evaluator") as info:
        check_fit(needs, made[1:-2])  # two bundles short
    assert "\n" not in str(info.value)


def test_the_robot_servers_are_a_row_of_the_table() -> None:
    """With --sim-path grpc, one robot server per env (and the evaluator's), each with the
    server's CPUs and mark: what the supervisor starts them with and the CPU check counts."""
    cfg = TrainConfig(workers=2, envs_per_worker=3, sim_path="grpc", server_resource="sim")
    server = actor_need(cfg, "robot server")
    assert (server.count, server.cpus) == (2 * 3 + 1, 0.2)
    assert server.options() == {"num_cpus": 0.2, "resources": {"sim": 0.01}}
    # learner 0.5, two workers at 0.25, evaluator 0.1, supervisor 0.05, seven servers at 0.2
    assert total_cpus(actor_needs(cfg)) == pytest.approx(0.5 + 0.5 + 0.1 + 0.05 + 1.4)
    inprocess = TrainConfig(workers=2, envs_per_worker=3)
    assert actor_need(inprocess, "robot server").count == 0
    assert "robot server" not in [n.role for n in actor_needs(inprocess)]
