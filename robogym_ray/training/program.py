"""Building a training program: every actor of one run, what it runs and where, in one place.

======================  ==============================  =========================================
actor                   runs                            placed (Ray options, beside its CPUs)
======================  ==============================  =========================================
supervisor (gRPC path)  robot-server actors             ``--server-resource`` on the servers
learner                 ``LearnerService``: replay,     ``--learner-cpus``/``--learner-gpus``,
                        D4PG steps, checkpoints to the  ``--learner-resource``; Ray restarts it
                        run's storage                   (on any node that fits) from storage
rollout workers         ``RolloutWorker`` x K envs;     ``--worker-cpus``, ``--worker-resource``
                        batches -> learner directly     (+ ``--server-resource`` in-process),
                                                        spread over nodes (``--spread-workers``)
evaluator               ``Evaluator``: greedy episodes  ``--evaluator-cpus``/``-resource``
real robots             ``RealRobot``: safety filter    on the driver's node (never restarted)
======================  ==============================  =========================================

What each actor reserves (CPUs, GPUs, custom resources) is one row of ``resources.actor_needs``,
the table the CPU check and a sweep's placement-group bundles are made from too.

Every file of the run goes to one ``RunStorage`` (``--storage``/``--logdir``, + run name) that
all nodes reach: the learner writes its checkpoints there itself, the driver the rest.
"""

from __future__ import annotations

import logging
import os
from contextlib import suppress
from dataclasses import asdict
from pathlib import Path
from typing import Any

import numpy as np
import ray
from ray.exceptions import RayError

from robogym_ray.config import FLAGS, Words
from robogym_ray.distributed import remote, robot_actors
from robogym_ray.distributed.names import NAMESPACE
from robogym_ray.distributed.real_client import RealRobotClientFactory
from robogym_ray.distributed.storage_check import check_reachable
from robogym_ray.envs.inprocess import InProcessServerProvider
from robogym_ray.envs.registration import variant_id
from robogym_ray.errors import DiskWriteError
from robogym_ray.experience.revisits import FailedStartRevisits
from robogym_ray.experience.rollout import box_dims, make_gym_env
from robogym_ray.learner.checkpoint import RUN_CHECKPOINT, replay_path
from robogym_ray.learner.config import D4PGConfig
from robogym_ray.protocol.tls import read_ca
from robogym_ray.realrobot.safety import safety_for
from robogym_ray.robots.emulation import EmulationConfig
from robogym_ray.storage import RunStorage, local_file
from robogym_ray.training import setup
from robogym_ray.training.config import TrainConfig
from robogym_ray.training.presets import TaskPreset, resolve_task
from robogym_ray.training.resources import ActorNeed, actor_need
from robogym_ray.training.selection import PolicySnapshots, SnapshotSelector
from robogym_ray.training.stats import WorkerSlot
from robogym_ray.training.supervision import start_supervision

log = logging.getLogger(__name__)


class Program:
    """The actors of one run, in ``place`` (``setup.run_place``: its name and storage, resolved
    and checked once). Built in ``__init__`` (stopped again if any fails to start);
    ``shutdown`` stops every one of them."""

    def __init__(
        self,
        cfg: TrainConfig,
        d4pg: D4PGConfig,
        preset: TaskPreset,
        emulation: EmulationConfig,
        place: setup.RunPlace,
        words: Words = FLAGS,
    ) -> None:
        self.cfg, self.d4pg, self.preset, self.emulation = cfg, d4pg, preset, emulation
        self.name = place.name
        setup.check_resources(cfg, words=words)  # the joined cluster's CPUs
        check_reachable(place.root)  # before anything of the run is written or started
        self.storage = place.storage
        try:
            # Where this process writes (TensorBoard, policy files): the storage's folder for a
            # path, a local folder uploaded from for an object store.
            self.run_dir = self.storage.staging("")
        except OSError as exc:  # a full disk: one line, not a traceback
            raise DiskWriteError.of("run directory", self.storage.location(), exc) from None
        self.supervision = start_supervision(cfg, preset.env_id, self.name)
        self.learner: Any = None
        self.evaluator: Any = None
        self.workers: list[WorkerSlot] = []
        self.real_robots: list[Any] = []
        try:
            self._start_actors()
        except BaseException:
            # Ray would end these actors too once their handles are collected (ownership), but
            # only when garbage collection gets there; the one cleanup path stops them now.
            self.shutdown()
            raise

    def _start_actors(self) -> None:
        cfg, d4pg, env_id = self.cfg, self.d4pg, self.preset.env_id
        probe = make_gym_env(env_id)()  # dimensions only: it never resets, so no server
        self.obs_dim, self.act_dim = box_dims(probe)
        probe.close()
        # check_inputs checked its spaces against the task's; this resolves a short name.
        self.eval_env_id = resolve_task(cfg.eval_env_id).env_id if cfg.eval_env_id else env_id
        if cfg.init_from:
            seed_checkpoint(cfg.init_from, self.storage, d4pg, self.obs_dim, self.act_dim)
        self.learner = remote.LearnerActor.options(
            **self._need("learner").options(),
            max_restarts=3,
            max_task_retries=0,
            name=f"learner-{self.name}",
            namespace=NAMESPACE,
        ).remote(
            d4pg, self.obs_dim, self.act_dim, seed=cfg.seed,
            storage=self.storage, checkpoint_every=cfg.checkpoint_every,
            replay_snapshot_every_s=cfg.replay_snapshot_every_s,
        )  # fmt: skip
        # The learner's first call: its answer is the state the run starts from. It is read
        # before the loop asks any worker to collect (a worker adds to the learner only in
        # collect), so no batch is counted in it. The workers and the evaluator start while the
        # learner's process does (importing torch takes seconds), not after it.
        first_status = self.learner.status.remote()
        self.workers = self._start_workers()
        if cfg.evaluator:
            self.evaluator = self._evaluator_actor()
        # A continued run starts at the checkpoint's step count; rates count this run's steps.
        status = ray.get(first_status)
        self.first_learner_step, self.first_total_added = status["version"], status["total_added"]
        log.info("learner on %s: %s, %d torch threads", status["node"], status["device"],
                 status["threads"])  # fmt: skip
        checkpoints = self.storage.child("checkpoints")
        staged = self.run_dir / "checkpoints"
        selecting = cfg.select_episodes and self.evaluator is not None
        self.selector = SnapshotSelector(staged, checkpoints) if selecting else None
        self.snapshots = PolicySnapshots(staged, cfg.policy_snapshot_every_s, checkpoints)

    def _need(self, role: str) -> ActorNeed:
        """An actor's Ray options: its row of the table a sweep's bundles come from (read when
        the actor starts: a replacement follows the config as it is then)."""
        return actor_need(self.cfg, role, learner_gpus(self.cfg))

    def _env_kwargs(self, index: int | None, env_id: str | None = None) -> dict[str, Any]:
        """Sim envs build their robots in their own process (``sim_path="inprocess"``) or lease
        servers from the supervisor, as holder ``worker-INDEX`` (the evaluator, index None:
        ``evaluator``); the first ``emulated_workers`` get emulated robots, the evaluator never.
        ``env_id``: the env they are for (default the task's; the evaluator's may differ)."""
        if not (env_id or self.preset.env_id).startswith("RoboGymRay/"):
            return {}
        emulated = (
            self.emulation if index is not None and index < self.cfg.emulated_workers else None
        )
        if self.supervision is None:
            return {"provider": InProcessServerProvider(emulation=emulated)}
        holder = "evaluator" if index is None else f"worker-{index}"
        return {"provider": self.supervision.provider(emulated, holder=holder)}

    def _start_workers(self) -> list[WorkerSlot]:
        cfg = self.cfg
        n = cfg.rollout_workers
        self._sigmas = worker_sigmas(self.d4pg, cfg, n)
        slots = []
        for i in range(n):
            if i < cfg.workers:
                slots.append(WorkerSlot(i, self._rollout_actor(i), "sim"))
            else:
                factory = self._real_env(i - cfg.workers)
                slots.append(WorkerSlot(i, self._rollout_actor(i, factory), "real"))
        return slots

    def _rollout_actor(self, i: int, real_env: Any = None, generation: int = 0) -> Any:
        cfg = self.cfg
        factory = real_env or make_gym_env(self.preset.env_id, self._env_kwargs(i))
        name = f"rollout-{self.name}-{i}" + (f"-{generation}" if generation else "")
        # A real robot's worker goes anywhere: it reaches its robot through the real-robot actor.
        placement = self._need("real-robot worker" if real_env else "rollout worker").options()
        if cfg.spread_workers and not real_env:
            placement["scheduling_strategy"] = "SPREAD"
        return remote.RolloutActor.options(
            name=name, namespace=NAMESPACE, **placement
        ).remote(
            factory, self.d4pg, index=i, sigma=self._sigmas[i], seed=cfg.seed + i,
            random_steps=cfg.random_steps,
            revisits=revisits_for(cfg, i) if real_env is None else None,
            num_envs=1 if real_env else cfg.envs_per_worker, learner=self.learner,
            real_robot=real_env is not None,
            relabel_goals=0 if real_env else cfg.relabel_goals,
        )  # fmt: skip

    def _evaluator_actor(self, generation: int = 0, first_episode: int = 0) -> Any:
        cfg, env_id = self.cfg, self.eval_env_id
        kwargs = self._env_kwargs(None, env_id) | evaluator_env_kwargs(cfg, env_id)
        name = f"evaluator-{self.name}" + (f"-{generation}" if generation else "")
        return remote.EvaluatorActor.options(
            name=name, namespace=NAMESPACE, **self._need("evaluator").options(),
        ).remote(
            make_gym_env(env_id, kwargs), self.d4pg,
            seed=cfg.seed + 10_000, video_every_s=cfg.video_interval_s,
            first_episode=first_episode,
        )  # fmt: skip

    def replace_evaluator(self, generation: int, first_episode: int) -> None:
        """Start a new evaluator in a dead one's place (its process or its node lost): with
        supervised servers it leases the one the dead one held, released here; it goes on
        from the episodes the dead one reported (its count and seeds; its window of rates
        starts empty)."""
        self.drop_evaluator()  # one that only failed to answer in time is not left running
        if self.supervision is not None:
            self.supervision.release_holder("evaluator")
        self.evaluator = self._evaluator_actor(generation, first_episode)

    def drop_evaluator(self) -> None:
        """Kill the evaluator (gone already, or not answering) and run on without one."""
        with suppress(RayError):
            ray.kill(self.evaluator)
        self.evaluator = None

    def replace_worker(self, slot: WorkerSlot) -> bool:
        """Start a new rollout worker in a simulated worker's place: it leases the server the
        dead one held (released here). A real robot's worker is never replaced: its robot
        may need an operator. Returns whether the slot has a live worker again."""
        if slot.kind != "sim":
            return False
        if self.supervision is not None:
            self.supervision.release_holder(f"worker-{slot.index}")
        slot.generation += 1
        slot.handle = self._rollout_actor(slot.index, generation=slot.generation)
        slot.steps_since_sync, slot.weights_version = 0, -1  # weights before its first call
        return True

    def _real_env(self, k: int) -> Any:
        actor, factory = real_robot(self.cfg, self.preset.env_id, self.name, k)
        self.real_robots.append(actor)
        return factory

    def config_record(self) -> dict[str, Any]:
        return config_record(self.cfg, self.d4pg, self.emulation)

    def restart_counts(self) -> dict[str, int]:
        return {} if self.supervision is None else self.supervision.restart_counts()

    def servers_given_up(self) -> int:
        return 0 if self.supervision is None else self.supervision.given_up()

    def server_nodes(self) -> list[dict[str, Any]]:
        return [] if self.supervision is None else self.supervision.server_nodes()

    def shutdown(self) -> None:
        for slot in self.workers:
            ray.kill(slot.handle)
        for actor in (self.evaluator, self.learner, *self.real_robots):
            if actor is not None:
                ray.kill(actor)
        if self.supervision is not None:
            self.supervision.stop()


# -- what the builder computes for each actor ----------------------------------------------
def worker_sigmas(d4pg: D4PGConfig, cfg: TrainConfig, n: int) -> list[float]:
    """Ape-X style: a spread of exploration noises from d4pg.sigma down to sigma_min."""
    if n <= 1:
        return [d4pg.sigma] * n
    return list(np.linspace(d4pg.sigma, min(cfg.sigma_min, d4pg.sigma), n))


def revisits_for(cfg: TrainConfig, index: int) -> FailedStartRevisits | None:
    """Worker ``index``'s failed-start revisits (None when cfg.revisit_failed is 0)."""
    if cfg.revisit_failed <= 0:
        return None
    return FailedStartRevisits(
        cfg.revisit_failed, cfg.revisit_pool, cfg.revisit_max, seed=cfg.seed + index
    )


def learner_gpus(cfg: TrainConfig) -> float:
    if cfg.learner_gpus >= 0:
        return cfg.learner_gpus
    return 1.0 if ray.cluster_resources().get("GPU", 0) >= 1 else 0.0


def seed_checkpoint(
    init_from: str, storage: RunStorage, d4pg: D4PGConfig, obs_dim: int, act_dim: int
) -> bool:
    """Copy ``init_from`` (and its replay; a path or an object store's URI) into the run's
    ``checkpoints/`` in ``storage``, for the learner to restore.

    Checked (``check_init_from``) before anything is copied. Returns False (and copies nothing)
    when the run already has its own checkpoint (a ``--resume``d run: it is newer).
    """
    target = RUN_CHECKPOINT
    if storage.exists(target):
        log.warning("%s exists; --init-from %s is not used", storage.location(target), init_from)
        return False
    source = Path(local_file(init_from, "--init-from"))
    state = setup.check_init_from(str(source), d4pg, obs_dim, act_dim)
    # The replay first: learner.pt marks the run's own checkpoint, so a copy cut off by a full
    # disk leaves none, and the re-run copies again (copy_file leaves no partial file).
    if replay_path(source).is_file():
        storage.upload(replay_path(source), replay_path(target).as_posix(), "learner replay")
    storage.upload(source, target, "learner checkpoint")
    log.info("continuing from %s (step %d)", init_from, int(state["num_steps"]))
    return True


def evaluator_env_kwargs(cfg: TrainConfig, env_id: str) -> dict[str, Any]:
    """What the evaluator's env needs beyond a worker's: frames for eval/video (our envs only)."""
    if cfg.video_interval_s <= 0 or not env_id.startswith("RoboGymRay/"):
        return {}
    from robogym_ray.envs.render import RenderConfig

    return {"render_mode": "rgb_array", "render_config": RenderConfig(width=320, height=240)}


def real_robot(cfg: TrainConfig, env_id: str, run_name: str, k: int) -> tuple[Any, Any]:
    """The real-robot actor for ``cfg.real_robot[k]`` and an env factory for the task's Rob
    variant that reaches the robot only through it (safety filter, pause on errors)."""
    address = cfg.real_robot[k]
    name = f"real-{run_name}-{k}"
    rob_id = variant_id(env_id, "rob")
    token = cfg.token or os.environ.get("ROBOGYM_RAY_TOKEN") or None
    tls_ca = read_ca(cfg.tls_ca)  # bytes: the actor may run on a node without the file
    actor = robot_actors.start_real_robot(
        name, address, safety_for(rob_id), token=token, tls_ca=tls_ca
    )
    kwargs = {"rs_address": address, "client_factory": RealRobotClientFactory(name)}
    return actor, make_gym_env(rob_id, kwargs)


def config_record(cfg: TrainConfig, d4pg: D4PGConfig, emulation: EmulationConfig) -> dict:
    """What ``config.json`` holds: a config file ``--config`` reads back (never the token)."""
    train = asdict(cfg) | ({"token": None} if cfg.token else {})
    record = {"train": train, "d4pg": asdict(d4pg)}
    if cfg.emulated_workers:
        record["emulation"] = asdict(emulation)
    return record
