"""The distributed training program on a local Ray (num_cpus=2): the issue's acceptance runs."""

from __future__ import annotations

import argparse
import io
import json
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import ray

from robogym_ray import children
from robogym_ray.distributed import names, robot_actors
from robogym_ray.errors import ConfigError
from robogym_ray.robots.emulation import EmulationConfig
from robogym_ray.robots.serve import serve_process
from robogym_ray.training import command as train_cmd
from robogym_ray.training.config import TrainConfig
from robogym_ray.training.run import run_training

pytestmark = [pytest.mark.ray, pytest.mark.slow, pytest.mark.usefixtures("ray_cluster")]

NAV = "RoboGymRay/ObstacleAvoidanceMir100Sim-v0"
EXPECTED_TAGS = {
    "episode/return",
    "train/success_rate",
    "train/collision_rate",
    "train/timeout_rate",
    "eval/success_rate",
    "eval/collision_rate",
    "eval/timeout_rate",
    "loss/critic",
    "loss/policy",
    "learner/mean_q",
    "replay/mean_priority",
    "replay/size",
    "throughput/env_steps_per_s",
    "throughput/learner_steps_per_s",
    "weights/lag",
    "explore/revisit_fraction",
    "explore/revisit_success_rate",
}


def scalar_tags(run_dir: str) -> set[str]:
    from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

    acc = EventAccumulator(run_dir)
    acc.Reload()
    return set(acc.Tags()["scalars"])


def eval_video(run_dir: str) -> Any:
    """The first eval/video image event (an animated GIF)."""
    from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

    acc = EventAccumulator(run_dir, size_guidance={"images": 0})
    acc.Reload()
    return acc.Images("eval/video")[0]


def test_navigation_run_completes_with_tensorboard_scalars(
    tmp_path: Path, selecting_run: dict
) -> None:
    cfg = TrainConfig(
        task=NAV,
        workers=2,
        total_steps=3000,
        logdir=str(tmp_path),
        run_name="nav",
        progress=False,
        log_every_s=1.0,
        revisit_failed=1.0,  # the untrained policy fails: the next start of a worker revisits
        policy_snapshot_every_s=2.0,
        eval_interval_s=1e6,  # one evaluator call: the first, filmed (checked below)
    )
    summary = run_training(cfg)
    # --eval-interval-s spaces the evaluator's calls: the first call, then none for 10^6 s,
    # where the default (0: back to back) makes several in a run of Pendulum's length.
    assert len(summary["eval_history"]) == 1
    assert len(selecting_run["eval_history"]) > 1
    # Timed policy snapshots at 2 s marks (the one the run ended on too), where evaluate and
    # peers.py evaluate read them; each taken after its mark, never a mark later.
    kept = summary["policy_snapshots"]
    assert kept and all(Path(k["path"]).exists() for k in kept)
    marks = [k["wall_min"] * 60 for k in kept]
    assert len(marks) >= 2 and marks == sorted(set(marks))
    # saved_at_min is rounded to 0.01 min (0.6 s)
    assert all(-0.6 < k["saved_at_min"] * 60 - k["wall_min"] * 60 < 2.0 + 0.6 for k in kept)
    assert summary["env_steps"] >= 3000
    assert summary["learner_steps"] > 0 and summary["episodes"] > 0
    # Workers send their batches to the learner themselves: every transition reached replay.
    assert summary["lost_transitions"] == 0
    # Revisits are counted apart from the task's own starts (whose rates train/ reports).
    assert 0 < summary["revisited_episodes"] < summary["episodes"]
    assert summary["explore/revisit_fraction"] > 0
    assert Path(summary["checkpoint"]).exists()
    tags = scalar_tags(str(tmp_path / "nav"))
    assert tags >= EXPECTED_TAGS, EXPECTED_TAGS - tags
    assert (tmp_path / "nav" / "summary.json").exists()
    # The first evaluation is filmed (video_interval_s defaults to 300 s): an animated GIF.
    from PIL import Image

    video = eval_video(str(tmp_path / "nav"))
    gif = Image.open(io.BytesIO(video.encoded_image_string))
    assert gif.format == "GIF" and gif.size == (320, 240) == (video.width, video.height)
    assert gif.n_frames > 2


def _kill_when(condition: Any, pid_of: Any, done: threading.Event, log: list[str]) -> None:
    """Background fault injector: SIGKILL ``pid_of()`` once ``condition()`` holds."""
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and not done.is_set():
        try:
            if condition():
                pid = pid_of()
                os.kill(pid, signal.SIGKILL)
                log.append(f"killed {pid}")
                return
        except Exception as exc:  # noqa: BLE001 - actors may not exist yet
            log.append(repr(exc))
        time.sleep(0.5)


def test_killing_a_robot_server_a_worker_and_the_learner_mid_run(tmp_path: Path) -> None:
    run = "faults"
    cfg = TrainConfig(
        task=NAV,
        workers=2,
        sim_path="grpc",  # supervised robot-server actors, one per worker
        envs_per_worker=1,
        total_steps=3000,
        logdir=str(tmp_path),
        run_name=run,
        progress=False,
        # Regular checkpoints come between a snapshot and the learner's kill, as in a real run
        # (defaults: 300 s, 500 steps); they once deleted it: the learner came back empty.
        checkpoint_every=20,
        replay_snapshot_every_s=5.0,
    )
    done = threading.Event()
    log: list[str] = []
    snapshot: dict[str, float] = {"mtime": 0.0, "transitions": 0}

    def supervisor() -> Any:
        return ray.get_actor(names.run_supervisor_name(run), namespace=names.NAMESPACE)

    def learner() -> Any:
        return ray.get_actor(f"learner-{run}", namespace=names.NAMESPACE)

    def servers_up() -> bool:
        servers = ray.get(supervisor().status.remote())
        return len([s for s in servers if s["pid"] and s["holder"].startswith("worker-")]) >= 2

    def worker_0_stepping() -> bool:
        # Mid-episode, not before worker 0's first reset: a server killed before the worker
        # ever used it fails a reset, which ends no episode (no server_restarted status).
        worker = ray.get_actor(f"rollout-{run}-0", namespace=names.NAMESPACE)
        return servers_up() and int(ray.get(worker.ping.remote(), timeout=30)) >= 100

    def server_pid() -> int:  # worker 0's: worker 1 is killed too, and could not report its end
        servers = ray.get(supervisor().status.remote())
        return next(s["pid"] for s in servers if s["pid"] and s["holder"] == "worker-0")

    def learner_past_a_snapshot() -> bool:  # of 300+ transitions, and a checkpoint 1 s later
        checkpoints = tmp_path / run / "checkpoints"
        replay = checkpoints / "learner.pt.replay.npz"
        if replay.exists() and replay.stat().st_mtime != snapshot["mtime"]:
            mtime = replay.stat().st_mtime
            with np.load(replay) as data:
                snapshot.update(mtime=mtime, transitions=int(data["counters"][1]))
        later = (checkpoints / "learner.pt").stat().st_mtime - snapshot["mtime"]
        return snapshot["transitions"] >= 300 and later >= 1.0

    def learner_pid() -> int:
        return int(ray.get(learner().status.remote())["pid"])

    def worker_pid() -> int:
        worker = ray.get_actor(f"rollout-{run}-1", namespace=names.NAMESPACE)
        return int(ray.get(worker.pid.remote()))

    injectors = [
        threading.Thread(target=_kill_when, args=(worker_0_stepping, server_pid, done, log)),
        threading.Thread(target=_kill_when, args=(learner_past_a_snapshot, learner_pid, done, log)),
        threading.Thread(target=_kill_when, args=(servers_up, worker_pid, done, log)),
    ]
    for t in injectors:
        t.start()
    try:
        # The restarted learner restores its replay snapshot; a small warm-up lets it train
        # again within this short run however late the kill lands.
        summary = run_training(cfg, {"min_replay_size": 256})
    finally:
        done.set()
        for t in injectors:
            t.join()
    assert sum("killed" in line for line in log) == 3, log
    assert summary["env_steps"] >= 3000
    # The killed rollout worker was replaced (it leased the server the dead one held) and
    # its replacement collected: both workers' steps are there.
    assert summary["faults/worker_failures"] == 1 == summary["faults/worker_replacements"]
    assert summary["worker_steps"]["1"] > 0
    # The robot server's crash was detected, the server restarted and counted once, with its
    # cause; the learner's death once, however many calls it failed.
    assert summary["restarts"]["connection"] == 1 == sum(summary["restarts"].values())
    assert summary["faults/learner_failures"] == 1
    # The worker whose server died ended that episode and dropped its unfinished n-step window,
    # so no transition in replay spans the crash.
    assert summary["final_status_counts"].get("server_restarted", 0) >= 1
    assert summary["dropped_steps"] >= 1
    # The learner came back from its checkpoint and training continued past it, with the replay
    # of its last snapshot: only what came after it was lost, and the summary says how much.
    assert summary["learner_restored_from_step"] >= 0  # -1: nothing was restored
    assert summary["learner_steps"] > summary["learner_restored_from_step"]
    assert summary["learner_restored_replay"] >= snapshot["transitions"] >= 300
    # The evaluator's call that held the dead learner's weights failed; evaluation went on.
    assert summary["eval_history"][-1]["learner_steps"] > summary["learner_restored_from_step"]
    assert 0 <= summary["lost_transitions"] < summary["env_steps"]


TOKEN = "s3cret"


@pytest.fixture
def real_mir100() -> Any:
    """`robogym-ray serve --real-time --token` in its own process: the stand-in for a real
    MiR100 on a network, so it wants a token."""
    args = ["--robot", "mir100", "--scene", "lab_6x8", "--real-time", "--port", "0"]
    with serve_process([*args, "--token", TOKEN]) as a:
        yield a


def test_mixed_sim_and_real_robot_workers(tmp_path: Path, real_mir100: str) -> None:
    cfg = TrainConfig(
        task=NAV,
        workers=1,
        real_robot=(real_mir100,),
        token=TOKEN,
        total_steps=600,
        logdir=str(tmp_path),
        run_name="mixed",
        progress=False,
        evaluator=False,
        steps_per_call=20,
    )
    summary = run_training(cfg)
    assert summary["env_steps"] >= 600
    # Worker 1 drove the real-time "real" robot (10 actions/s) through its real-robot actor.
    assert summary["worker_steps"]["0"] > 0 and summary["worker_steps"]["1"] > 0
    assert summary["robot_errors"] == 0
    config = json.loads((tmp_path / "mixed" / "config.json").read_text())
    assert config["train"]["token"] is None  # the secret stays out of the run directory


def test_a_paused_real_robot_does_not_keep_a_run_from_ending(tmp_path: Path) -> None:
    """Its server is killed after the robot has driven a while: the real-robot actor pauses
    the robot (until an operator resumes it) and its worker's calls return nothing; the
    simulated worker collects the rest and the run ends with a checkpoint and a summary.
    Before, the paused worker's call counted as steps in flight, so the simulated worker was
    never re-queued and the run never ended."""
    cmd = [sys.executable, "-m", "robogym_ray.cli", "serve", "--robot", "mir100",
           "--scene", "lab_6x8", "--real-time", "--port", "0"]  # fmt: skip
    server = children.popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
    assert server.stdout is not None
    address = server.stdout.readline().strip().removeprefix("listening on ")
    cfg = TrainConfig(
        task=NAV, workers=1, real_robot=(address,), total_steps=6000, steps_per_call=20,
        logdir=str(tmp_path), run_name="paused", progress=False, evaluator=False,
        real_robot_wait_s=5.0,
    )  # fmt: skip

    def robot_has_driven() -> bool:  # its worker's steps, counted after each of its calls
        worker = ray.get_actor("rollout-paused-1", namespace=names.NAMESPACE)
        return int(ray.get(worker.ping.remote(), timeout=30)) > 0

    done = threading.Event()
    log: list[str] = []
    killer = threading.Thread(
        target=_kill_when, args=(robot_has_driven, lambda: server.pid, done, log)
    )
    killer.start()
    started = time.monotonic()
    try:
        summary = run_training(cfg)
    finally:
        done.set()
        killer.join()
        server.kill()
        server.wait()
    assert any("killed" in line for line in log), log
    assert time.monotonic() - started < 300
    assert summary["env_steps"] >= 6000 and summary["faults/worker_failures"] == 0
    assert summary["worker_steps"]["1"] > 0 and summary["robot_errors"] >= 1
    assert Path(summary["checkpoint"]).exists()
    assert (tmp_path / "paused" / "summary.json").exists()


def test_a_run_that_cannot_fit_the_cluster_is_refused(tmp_path: Path) -> None:
    cfg = TrainConfig(task=NAV, workers=8, total_steps=10, logdir=str(tmp_path), progress=False)
    with pytest.raises(ConfigError, match="Ray CPUs"):
        run_training(cfg)


def pendulum(tmp_path: Path, run_name: str, total_steps: int, **more: Any) -> TrainConfig:
    """A one-worker Pendulum-v1 run (no robot servers): the cheapest real training."""
    return TrainConfig(task="pendulum", workers=1, total_steps=total_steps, logdir=str(tmp_path),
                       run_name=run_name, progress=False, random_steps=200, **more)  # fmt: skip


def test_a_learner_restarted_with_nothing_to_restore_ends_the_run(tmp_path: Path) -> None:
    """No checkpoint (--checkpoint-every 0): the learner Ray restarts after a kill finds
    nothing, so the run stops in one line saying what was lost, rather than train on from
    scratch as if it were the same run; no checkpoint of fresh networks is written."""
    from robogym_ray.errors import LearnerLostError

    run = "lost"
    cfg = pendulum(tmp_path, run, 10_000_000, max_wall_s=120.0, checkpoint_every=0,
                   replay_snapshot_every_s=0.0, evaluator=False)  # fmt: skip
    done, log = threading.Event(), []

    def learner() -> Any:
        return ray.get_actor(f"learner-{run}", namespace=names.NAMESPACE)

    def trained() -> bool:
        return int(ray.get(learner().status.remote())["version"]) >= 50

    def learner_pid() -> int:
        return int(ray.get(learner().status.remote())["pid"])

    killer = threading.Thread(target=_kill_when, args=(trained, learner_pid, done, log))
    killer.start()
    try:
        with pytest.raises(LearnerLostError) as info:
            run_training(cfg, {"min_replay_size": 256})
    finally:
        done.set()
        killer.join()
    message = str(info.value)
    assert message.startswith("the learner restarted on ") and "found no checkpoint" in message
    assert "learner steps it had taken and its replay are lost" in message, message
    assert "\n" not in message
    summary = json.loads((tmp_path / run / "summary.json").read_text())
    assert summary["ended"] == "failed" and message.startswith(summary["error"])
    assert message.endswith(f"no checkpoint; summary: {tmp_path / run / 'summary.json'}")
    assert summary["checkpoint"] is None
    assert not (tmp_path / run / "checkpoints" / "learner.pt").exists()
    assert any(line.startswith("killed") for line in log), log


def test_a_run_continues_from_another_runs_checkpoint_and_replay(tmp_path: Path) -> None:
    # No evaluator: nothing here reads its rates, and each of the three runs would start one
    # and play its final evaluation.
    common = dict(task="pendulum", workers=1, logdir=str(tmp_path), progress=False, evaluator=False)
    small = {"min_replay_size": 256}
    first = run_training(
        TrainConfig(
            **common, run_name="first", total_steps=600, random_steps=200, save_replay=True
        ),
        small,
    )
    assert first["learner_steps"] > 0
    checkpoint = Path(first["checkpoint"])
    assert Path(f"{checkpoint}.replay.npz").exists()
    second = run_training(
        TrainConfig(**common, run_name="second", total_steps=200, init_from=str(checkpoint)),
        small,
    )
    assert second["learner_restored_from_step"] == first["learner_steps"]
    assert second["learner_steps"] > first["learner_steps"]
    with pytest.raises(ConfigError, match="init-from"):
        run_training(TrainConfig(**common, run_name="third", init_from=str(tmp_path / "x.pt")))
    # The first run, resumed in its own folder until its wall limit: the summary says why each
    # part ended, and counts this part and the whole run.
    assert first["ended_by"] == "total_steps" and not first["resumed"]
    again = run_training(
        TrainConfig(**common, run_name="first", resume=True, total_steps=10**9, max_wall_s=3.0),
        small,
    )
    assert again["ended"] == "completed" and again["ended_by"] == "max_wall_s" and again["resumed"]
    assert again["this_part"]["part"] == 2 and again["this_part"]["env_steps"] == again["env_steps"]
    whole = again["whole_run"]
    assert whole["parts"] == 2 and whole["complete"]
    for key in ("env_steps", "episodes", "learner_steps"):
        assert whole[key] == first["whole_run"][key] + again["this_part"][key], key
    assert whole["learner_steps"] == again["learner_steps"]  # the learner's own count
    text = train_cmd.summary_text(again)
    assert "Trained Pendulum-v1 part 2 (resumed): " in text and "ended at --max-wall-s" in text
    assert "  whole run:   2 parts, " in text


def test_emulated_workers_train_on_emulated_robots_and_the_evaluator_does_not(
    tmp_path: Path,
) -> None:
    """Domain randomisation: worker 0 leases an emulated MiR100, worker 1 and the evaluator the
    plain simulation; config.json records the emulation and reads back through --config."""
    run = "dr"
    cfg = TrainConfig(
        task=NAV,
        workers=2,
        emulated_workers=1,
        sim_path="grpc",  # supervised servers, which the watcher can see (in-process: below)
        envs_per_worker=1,
        total_steps=1500,
        logdir=str(tmp_path),
        run_name=run,
        progress=False,
    )
    emulation = EmulationConfig(laser_noise_sigma=0.03, latency_ticks=2)
    seen: list[list[bool]] = []
    done = threading.Event()

    def watch() -> None:
        while not done.is_set():
            sup = robot_actors.get_supervisor(names.run_supervisor_name(run))
            if sup is not None:
                try:
                    servers = [s for s in ray.get(sup.status.remote()) if s["leased"]]
                except Exception:  # noqa: BLE001 - the run may be ending
                    servers = []
                if len(servers) == 3:
                    seen.append(sorted(s["emulated"] for s in servers))
                    return
            time.sleep(0.3)

    watcher = threading.Thread(target=watch)
    watcher.start()
    try:
        summary = run_training(cfg, None, emulation)
    finally:
        done.set()
        watcher.join()
    assert summary["env_steps"] >= 1500
    assert seen == [[False, False, True]]
    parser = argparse.ArgumentParser()
    train_cmd.add_arguments(parser)
    again = train_cmd.build_config(
        parser.parse_args(["--config", str(tmp_path / run / "config.json")])
    )
    assert again.emulation == emulation and again.train.emulated_workers == 1


@pytest.fixture(scope="module")
def selecting_run(tmp_path_factory: pytest.TempPathFactory, ray_cluster: None) -> dict:
    """A Pendulum run that scores its snapshots (evaluator calls back to back, the default):
    its summary, shared by the tests that read it."""
    root = tmp_path_factory.mktemp("selecting")
    return run_training(
        pendulum(root, "sel", 1500, select_episodes=1),
        {"min_replay_size": 256, "policy_average_tau": 0.05},
    )


def test_snapshot_selection_keeps_a_best_policy_that_evaluate_reads(selecting_run: dict) -> None:
    from robogym_ray.export import load_policy

    summary = selecting_run
    # With policy averaging the run ships (and evaluate loads) the average.
    final = load_policy(summary["checkpoint"])
    assert final.info.source.endswith("learner.pt#policy_average")
    best = summary["best_snapshot"]
    assert best["snapshots_scored"] >= 1 and Path(best["path"]).name == "policy-best.pt"
    assert len(summary["eval_history"]) == best["snapshots_scored"]  # every evaluation scored
    policy = load_policy(best["path"])  # what `robogym-ray evaluate` / `export` load
    assert policy.info.env_id == "Pendulum-v1"
    assert policy(np.zeros(3)).shape == (1,)


def test_pendulum_runs_without_a_supervisor(selecting_run: dict) -> None:
    summary = selecting_run  # a task without robot servers: nothing to supervise or restart
    assert summary["env_steps"] >= 1500 and not any(summary["restarts"].values())


def test_in_process_workers_get_emulated_robots_and_the_evaluator_does_not() -> None:
    """The same split on the default path: worker 0's provider builds emulated robots, worker 1's
    and the evaluator's plain ones (the providers are all a program hands its actors)."""
    from robogym_ray.envs.inprocess import InProcessServerProvider
    from robogym_ray.training.presets import resolve_task
    from robogym_ray.training.program import Program

    program = Program.__new__(Program)  # the provider choice only: no actors
    program.cfg = TrainConfig(task=NAV, workers=2, emulated_workers=1)
    program.preset, program.supervision = resolve_task(NAV), None
    program.emulation = EmulationConfig(laser_noise_sigma=0.03)
    providers = [program._env_kwargs(i)["provider"] for i in (0, 1, None)]
    assert all(isinstance(p, InProcessServerProvider) for p in providers)
    assert [p.emulation for p in providers] == [program.emulation, None, None]
