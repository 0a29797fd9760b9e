"""How a training run joins Ray and gets its robot servers (the supervisor hooks)."""

from __future__ import annotations

import json
import logging
import os
import time
from collections import Counter
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np
import ray

from robogym_ray.config import quote
from robogym_ray.distributed import remote
from robogym_ray.distributed.local_ray import join_ray, start_local_ray
from robogym_ray.distributed.provider import SupervisorServerProvider
from robogym_ray.distributed.real_client import RealRobotClientFactory
from robogym_ray.envs.registration import variant_id
from robogym_ray.errors import ConfigError
from robogym_ray.experience.revisits import FailedStartRevisits
from robogym_ray.experience.rollout import make_gym_env
from robogym_ray.learner import checkpoint
from robogym_ray.learner.checkpoint import CHECKPOINT_NAME, replay_path
from robogym_ray.learner.config import D4PGConfig
from robogym_ray.learner.learner import linear_ramp, make_adam
from robogym_ray.learner.networks import DistributionalCritic, Policy
from robogym_ray.realrobot.safety import safety_for
from robogym_ray.robots.emulation import EmulationConfig
from robogym_ray.storage import RunStorage, local_file, resolve_root
from robogym_ray.supervision.restart_policy import FaultCause
from robogym_ray.supervision.supervisor import SupervisorConfig
from robogym_ray.text import clip_text
from robogym_ray.training.config import TrainConfig
from robogym_ray.training.presets import resolve_task

log = logging.getLogger(__name__)


def ensure_ray(cfg: TrainConfig) -> bool:
    """Join ``cfg.address`` or start an embedded local Ray; True if this call started it."""
    if ray.is_initialized():
        return False
    if cfg.address:
        join_ray(cfg.address, log_to_driver=False)
    else:
        start_local_ray(cfg.num_cpus, log_to_driver=False)
    return True


def worker_sigmas(d4pg: D4PGConfig, cfg: TrainConfig, n: int) -> list[float]:
    """Ape-X style: a spread of exploration noises from d4pg.sigma down to sigma_min."""
    if n <= 1:
        return [d4pg.sigma] * n
    return list(np.linspace(d4pg.sigma, min(cfg.sigma_min, d4pg.sigma), n))


def noise_scale(cfg: TrainConfig, env_steps: int) -> float:
    """Factor on every worker's sigma after ``env_steps`` (the linear late decay)."""
    if cfg.sigma_decay_steps <= 0:
        return 1.0
    return linear_ramp(
        env_steps, cfg.sigma_decay_start, cfg.sigma_decay_steps, 1.0, cfg.sigma_final_scale
    )


def revisits_for(cfg: TrainConfig, index: int) -> FailedStartRevisits | None:
    """Worker ``index``'s failed-start revisits (None when cfg.revisit_failed is 0)."""
    if cfg.revisit_failed <= 0:
        return None
    return FailedStartRevisits(
        cfg.revisit_failed, cfg.revisit_pool, cfg.revisit_max, seed=cfg.seed + index
    )


def check_resources(cfg: TrainConfig, available: float | None = None) -> None:
    """Fail fast when the actors cannot all be scheduled (they would wait forever otherwise).

    ``available``: the CPUs to fit in (default: the joined Ray cluster's).
    """
    if available is None:
        available = float(ray.cluster_resources().get("CPU", 0.0))
    demand = cfg.cpu_demand()
    if demand > available + 1e-9:
        raise ConfigError(
            f"the run reserves {demand:.2f} Ray CPUs but the cluster has {available:g}: lower "
            f"--workers ({cfg.workers}), --worker-cpus ({cfg.worker_cpus}), --server-cpus "
            f"({cfg.server_cpus}) or --learner-cpus ({cfg.learner_cpus}), or add nodes"
        )


def learner_gpus(cfg: TrainConfig) -> float:
    if cfg.learner_gpus >= 0:
        return cfg.learner_gpus
    return 1.0 if ray.cluster_resources().get("GPU", 0) >= 1 else 0.0


@dataclass
class Supervision:
    """The supervisor a run uses: a running one (e.g. ``robogym-ray manager``) or its own."""

    actor: Any
    name: str
    owned: bool
    resources: tuple[tuple[str, float], ...] = ()

    def provider(
        self, emulation: EmulationConfig | None = None, holder: str = ""
    ) -> SupervisorServerProvider:
        return SupervisorServerProvider(
            name=self.name, resources=self.resources, emulation=emulation, holder=holder
        )

    def release_holder(self, holder: str) -> int:
        """End the leases of a worker that died (see ``Supervisor.release_holder``)."""
        return int(ray.get(self.actor.release_holder.remote(holder), timeout=30))

    def restart_counts(self) -> dict[str, int]:
        """Restarts by cause over every server of this supervisor."""
        # Every cause appears (zeros too), so TensorBoard shows the five faults from the start.
        counts: Counter[str] = Counter({cause.value: 0 for cause in FaultCause})
        for server in self._servers():
            counts.update(server.get("restarts", {}))
        return dict(counts)

    def given_up(self) -> int:
        """Servers the restart policy gave up (one fault past its limit: not a restart)."""
        return sum(server.get("state") == "given_up" for server in self._servers())

    def _servers(self) -> list[dict[str, Any]]:
        try:
            return list(ray.get(self.actor.status.remote(), timeout=10))
        except Exception:  # noqa: BLE001 - a dead supervisor must not stop the run's logging
            return []

    def server_nodes(self) -> list[dict[str, Any]]:
        """Where each running server is: its Ray node id and that node's custom resources."""
        nodes = {n["NodeID"]: n.get("Resources", {}) for n in ray.nodes() if n.get("Alive")}
        out = []
        for server in ray.get(self.actor.status.remote()):
            if server.get("pid"):
                res = nodes.get(server.get("node_id", ""), {})
                custom = {
                    k: v
                    for k, v in res.items()
                    if k not in ("CPU", "GPU", "memory", "object_store_memory")
                    and not k.startswith("node:")
                }
                out.append({"id": server["id"], "node_id": server.get("node_id", ""), **custom})
        return out

    def stop(self) -> None:
        if self.owned:
            try:
                ray.get(self.actor.shutdown.remote(), timeout=30)
            finally:
                ray.kill(self.actor, no_restart=True)


def start_supervision(cfg: TrainConfig, env_id: str, run_name: str) -> Supervision | None:
    """Supervision for RoboGymRay Sim tasks on the gRPC path; None for in-process simulation
    (the workers supervise their own) and for other envs (e.g. Pendulum-v1)."""
    if not env_id.startswith("RoboGymRay/") or cfg.sim_path != "grpc":
        return None
    resources = ((cfg.server_resource, 0.01),) if cfg.server_resource else ()
    running = remote.get_supervisor()
    if running is not None:
        log.warning("using the running supervisor %s", remote.SUPERVISOR_NAME)
        return Supervision(running, remote.SUPERVISOR_NAME, owned=False, resources=resources)
    name = f"{remote.SUPERVISOR_NAME}-{run_name}"
    actor = remote.start_supervisor(SupervisorConfig(server_num_cpus=cfg.server_cpus), name=name)
    return Supervision(actor, name, owned=True, resources=resources)


def learner_networks(
    d4pg: D4PGConfig, obs_dim: int, act_dim: int
) -> tuple[Policy, DistributionalCritic]:
    """The learner's two network classes for these settings, on CPU (a ConfigError for sizes
    torch refuses, e.g. a hidden layer of -5 units).

    Only these: a whole D4PGLearner would allocate its replay and set torch's threads, seed and
    denormal mode in this (driver) process.
    """
    try:
        policy = Policy(obs_dim, act_dim, d4pg.policy_hidden, d4pg.layer_norm)
        critic = DistributionalCritic(
            obs_dim, act_dim, d4pg.critic_hidden, d4pg.num_atoms, d4pg.layer_norm
        )
    except (RuntimeError, ValueError, TypeError) as exc:
        raise ConfigError(
            f"d4pg: no networks of policy_hidden={quote(d4pg.policy_hidden)}, "
            f"critic_hidden={quote(d4pg.critic_hidden)}: {clip_text(str(exc), 200)}"
        ) from None
    return policy, critic


def read_init_from(init_from: str, label: str = "--init-from") -> dict[str, Any]:
    """The learner checkpoint ``init_from``, checked as a file (readable, complete, its replay
    readable); what needs the task's dimensions is ``check_init_from``'s. ``label``: what the
    file is to the user, for the error."""
    source = Path(local_file(init_from, label))  # an object store's: downloaded once
    if not source.is_file():
        raise ConfigError(f"{label} {init_from}: no such checkpoint file")
    state = checkpoint.read(source)
    checkpoint.check_learner_state(state, source)
    if replay_path(source).is_file():
        checkpoint.check_replay(replay_path(source))
    return state


def check_init_from(
    init_from: str,
    d4pg: D4PGConfig,
    obs_dim: int,
    act_dim: int,
    state: dict[str, Any] | None = None,
    label: str = "--init-from",
) -> dict[str, Any]:
    """The learner checkpoint ``init_from`` (``state``: already read by ``read_init_from``),
    loaded into this run's networks and optimisers as the learner will, on CPU and writing
    nothing: a bad file fails before Ray starts, in one line, not in a learner actor that
    crashes and restarts."""
    if state is None:
        state = read_init_from(init_from, label)
    policy, critic = learner_networks(d4pg, obs_dim, act_dim)
    nets = state["nets"]
    try:
        for name in ("policy", "target_policy", "policy_average"):
            if name in nets:
                policy.load_state_dict(nets[name])
        for name in ("critic", "target_critic"):
            critic.load_state_dict(nets[name])
        make_adam(policy.parameters(), d4pg.policy_lr).load_state_dict(state["opts"]["policy"])
        make_adam(critic.parameters(), d4pg.critic_lr).load_state_dict(state["opts"]["critic"])
    except Exception as exc:  # noqa: BLE001 - any failure means "not a checkpoint for this run"
        raise ConfigError(
            f"{label} {init_from}: not a D4PG checkpoint for obs_dim={obs_dim}, "
            f"act_dim={act_dim}, policy_hidden={list(d4pg.policy_hidden)}, "
            f"critic_hidden={list(d4pg.critic_hidden)}, num_atoms={d4pg.num_atoms}, "
            f"layer_norm={d4pg.layer_norm} ({type(exc).__name__}: {clip_text(str(exc), 300)})"
        ) from None
    return state


def seed_checkpoint(
    init_from: str, storage: RunStorage, d4pg: D4PGConfig, obs_dim: int, act_dim: int
) -> bool:
    """Copy ``init_from`` (and its replay; a path or an object store's URI) into the run's
    ``checkpoints/`` in ``storage``, for the learner to restore.

    Checked (``check_init_from``) before anything is copied. Returns False (and copies nothing)
    when the run already has its own checkpoint (a ``--resume``d run: it is newer).
    """
    target = f"checkpoints/{CHECKPOINT_NAME}"
    if storage.exists(target):
        log.warning("%s exists; --init-from %s is not used", storage.location(target), init_from)
        return False
    source = Path(local_file(init_from, "--init-from"))
    state = check_init_from(str(source), d4pg, obs_dim, act_dim)
    # The replay first: learner.pt marks the run's own checkpoint, so a copy cut off by a full
    # disk leaves none, and the re-run copies again (copy_file leaves no partial file).
    if replay_path(source).is_file():
        storage.upload(replay_path(source), replay_path(target).as_posix(), "learner replay")
    storage.upload(source, target, "learner checkpoint")
    log.info("continuing from %s (step %d)", init_from, int(state["num_steps"]))
    return True


def run_name(cfg: TrainConfig, env_id: str) -> str:
    """``cfg.run_name``, or a new one: the task and the time, with ``-2``, ``-3``... when two
    runs start in the same second (a default name never lands in another run's folder)."""
    if cfg.run_name:
        return cfg.run_name
    root = RunStorage(storage_root(cfg))
    base = f"{env_id.split('/')[-1]}-{time.strftime('%Y%m%d-%H%M%S')}"
    name, n = base, 1
    while root.child(name).holds_run() or (root.is_local and (root.path / name).exists()):
        n += 1
        name = f"{base}-{n}"
    return name


def check_run_name(cfg: TrainConfig, env_id: str) -> None:
    """A run folder that holds a run already is continued only when asked (``--resume``), and
    only for the same task; ``--resume`` needs a checkpoint to continue from. One line each."""
    assert cfg.run_name
    storage = RunStorage(storage_root(cfg)).child(cfg.run_name)
    held = storage.holds_run()
    if held and not cfg.resume:
        raise ConfigError(
            f"run folder {storage.location()} holds a run already: pass --resume to continue "
            "it, or another --run-name (leave it out for a new name each run)"
        )
    if not cfg.resume:
        return
    if not storage.exists(f"checkpoints/{CHECKPOINT_NAME}"):
        raise ConfigError(f"--resume: {storage.location()} has no checkpoint to continue from")
    if storage.exists("config.json"):
        try:
            task = json.loads(storage.read_bytes("config.json"))["train"]["task"]
            earlier = resolve_task(task).env_id
        except (ValueError, KeyError, TypeError, ConfigError):
            return  # an unreadable record: the checkpoint's own check (shapes) still applies
        if earlier != env_id:
            raise ConfigError(
                f"--resume: {storage.location()} is a run of {earlier}, not {env_id}; pass "
                "another --run-name for a new run"
            )


def storage_root(cfg: TrainConfig) -> str:
    """Where the run's folder goes: ``--storage`` (else ``--logdir``), as every node sees it
    (``storage.resolve_root``: absolute, out of a Ray job's temporary working-dir copy)."""
    return resolve_root(cfg.storage or cfg.logdir)


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
    actor = remote.start_real_robot(name, address, safety_for(rob_id), token=token)
    kwargs = {"rs_address": address, "client_factory": RealRobotClientFactory(name)}
    return actor, make_gym_env(rob_id, kwargs)


def config_record(cfg: TrainConfig, d4pg: D4PGConfig, emulation: EmulationConfig) -> dict:
    """What ``config.json`` holds: a config file ``--config`` reads back (never the token)."""
    train = asdict(cfg) | ({"token": None} if cfg.token else {})
    record = {"train": train, "d4pg": asdict(d4pg)}
    if cfg.emulated_workers:
        record["emulation"] = asdict(emulation)
    return record
