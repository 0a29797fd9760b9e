"""What a run checks and decides before anything starts (its storage, its name, its resources,
the checkpoint it continues from), and how it joins Ray. The actors themselves are built in
``program.py``."""

from __future__ import annotations

import json
import logging
import os
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import ray

from robogym_ray.config import FLAGS, Words, check_dir_path, quote
from robogym_ray.distributed.local_ray import join_ray, start_local_ray
from robogym_ray.errors import ConfigError
from robogym_ray.experience.relabel import goal_task
from robogym_ray.experience.rollout import box_dims, make_gym_env
from robogym_ray.learner import checkpoint
from robogym_ray.learner.checkpoint import RUN_CHECKPOINT, replay_path
from robogym_ray.learner.config import D4PGConfig
from robogym_ray.learner.features import critic_features
from robogym_ray.learner.learner import make_adam
from robogym_ray.learner.networks import DistributionalCritic, Policy
from robogym_ray.learner.schedules import linear_ramp
from robogym_ray.storage import RunStorage, check_writable, is_uri, local_file, resolve_root
from robogym_ray.text import clip_text
from robogym_ray.training.config import TrainConfig
from robogym_ray.training.presets import d4pg_for, resolve_task
from robogym_ray.training.resources import actor_needs, describe, total_cpus
from robogym_ray.training.settings import TrainSetup

log = logging.getLogger(__name__)


def ensure_ray(address: str | None, num_cpus: float | None) -> bool:
    """Join ``address`` or start an embedded local Ray of ``num_cpus`` (None: this machine's);
    True if this call started it. In a Tune trial Ray is up already: nothing is done."""
    if ray.is_initialized():
        return False
    if address:
        join_ray(address, log_to_driver=False)
    else:
        start_local_ray(num_cpus, log_to_driver=False)
    return True


def noise_scale(cfg: TrainConfig, env_steps: int) -> float:
    """Factor on every worker's sigma after ``env_steps`` (the linear late decay)."""
    if cfg.sigma_decay_steps <= 0:
        return 1.0
    return linear_ramp(
        env_steps, cfg.sigma_decay_start, cfg.sigma_decay_steps, 1.0, cfg.sigma_final_scale
    )


def check_resources(
    cfg: TrainConfig,
    available: float | None = None,
    *,
    own: float = 0.0,
    hint: str = "",
    words: Words = FLAGS,
) -> None:
    """Fail fast when the actors cannot all be scheduled (they would wait forever otherwise).

    Args:
        available: the CPUs to fit in (default: the joined Ray cluster's).
        own: CPUs reserved beside the run's actors: a sweep trial's own actor (its driver).
        hint: what the caller's user may lower, in the caller's words (default: the CPU
            settings, in ``words``: train's flags or ``robogym_ray.train``'s keywords).
    """
    if available is None:
        available = float(ray.cluster_resources().get("CPU", 0.0))
    needs = actor_needs(cfg)
    demand = total_cpus(needs) + own
    if demand > available + 1e-9:
        given = [words.given(f, getattr(cfg, f)) for f in ("workers", "worker_cpus", "server_cpus")]
        hint = (
            hint or f"lower {', '.join(given)} or {words.given('learner_cpus', cfg.learner_cpus)}"
        )
        driver = f" + its driver {own:g} CPU" if own else ""
        raise ConfigError(
            f"the run reserves {demand:.2f} Ray CPUs ({describe(needs)}{driver}) but the "
            f"cluster has {available:g}: {hint}, or add nodes"
        )


def check_inputs(
    setup: TrainSetup, *, own_cpus: float = 0.0, cpu_hint: str = "", words: Words = FLAGS
) -> None:
    """Everything the run reads, checked before Ray starts or its run directory is made: the
    task, the D4PG settings, the CA file, the log directory, the local Ray's CPUs
    (``check_resources``, with ``own_cpus`` and ``cpu_hint``), ``--init-from``, the run name
    and that the storage can be written. Errors name the settings in ``words``: flags, or
    ``robogym_ray.train``'s keywords."""
    cfg = setup.train
    if cfg.resume and not cfg.run_name:  # a default name is a new, empty folder
        name = words.name("run_name")
        raise ConfigError(
            f"{words.setting('resume', True)} without {name}: expected the {name} of the run "
            "to resume (without one, a new, empty folder)"
        )
    try:
        preset = resolve_task(cfg.task)
    except ConfigError as exc:  # its message repeats the name whole: a 1 MB one too
        raise ConfigError(str(exc).replace(repr(cfg.task), quote(cfg.task))) from None
    d4pg = d4pg_for(preset, setup.d4pg, cfg)
    if cfg.tls_ca is not None:
        from robogym_ray.protocol.tls import read_ca  # grpc: only when asked for

        read_ca(cfg.tls_ca, words.label("tls_ca"))  # unreadable, or no certificate: one line
    if cfg.emulated_workers and not preset.env_id.startswith("RoboGymRay/"):
        raise ConfigError(
            f"{words.given('emulated_workers', cfg.emulated_workers)} needs a robot task; "
            f"{preset.env_id} has none"
        )
    root = storage_root(cfg)
    if not is_uri(root):
        local = Path(root) / cfg.run_name if cfg.run_name else Path(root)
        check_dir_path(local, "/".join(map(words.label, ("storage", "logdir", "run_name"))))
    if cfg.address is None:  # the local Ray gets num_cpus, or (at most) all of this machine
        available = cfg.num_cpus or float(os.cpu_count() or 1)
        check_resources(cfg, available, own=own_cpus, hint=cpu_hint, words=words)
    init_from, label = cfg.init_from, words.label("init_from")
    if cfg.run_name:  # a taken name without --resume, or --resume of another task: refused
        place = run_place(cfg, preset.env_id, words)
        if cfg.resume:
            # A resumed run continues from its own checkpoint and ignores --init-from
            # (seed_checkpoint); checked the same way (other network sizes would otherwise
            # crash its learner actor after Ray started).
            own = place.storage.location(RUN_CHECKPOINT)
            init_from, label = own, f"{words.setting('resume', True)}: the run's checkpoint"
    # The file first: probing the env below imports pybullet, whose banner goes to stderr.
    state = read_init_from(init_from, label) if init_from else None
    # A file written and removed at the root (the folders it needed too: nothing stays).
    check_writable(RunStorage(root), words.label("storage" if cfg.storage else "logdir"))
    probe = make_gym_env(preset.env_id)()  # dimensions only: it never resets, so no server
    try:
        obs_dim, act_dim = box_dims(probe)
        if cfg.relabel_goals:
            try:
                goal_task(probe, preset.env_id)
            except ConfigError as exc:
                given = words.given("relabel_goals", cfg.relabel_goals)
                raise ConfigError(f"{given}: {exc}") from None
        if cfg.eval_env_id is not None:
            check_eval_env(cfg.eval_env_id, probe, preset.env_id, words)
    finally:
        probe.close()
    if init_from:
        check_init_from(init_from, d4pg, obs_dim, act_dim, state, label)
    else:
        learner_networks(d4pg, obs_dim, act_dim)


def check_eval_env(eval_env_id: str, task_env: Any, task_id: str, words: Words = FLAGS) -> str:
    """The evaluator's env id for ``eval_env_id`` (an id, or a task's short name): registered,
    and with ``task_env``'s observation and action spaces, since the policy trained on
    ``task_id`` must run there unchanged. ConfigError otherwise."""
    given = words.given("eval_env_id", eval_env_id)
    try:
        env_id = resolve_task(eval_env_id).env_id
    except ConfigError as exc:
        raise ConfigError(f"{given}: {exc}") from None
    other = make_gym_env(env_id)()  # dimensions only, as the task's probe
    try:
        for name in ("observation_space", "action_space"):
            theirs, ours = getattr(other, name), getattr(task_env, name)
            if theirs != ours:
                raise ConfigError(
                    f"{given}: its {name.replace('_', ' ')} is {theirs}, the task {task_id}'s "
                    f"is {ours}; the evaluator's env must take the task's policy unchanged"
                )
    finally:
        other.close()
    return env_id


def learner_networks(
    d4pg: D4PGConfig, obs_dim: int, act_dim: int
) -> tuple[Policy, DistributionalCritic]:
    """The learner's two network classes for these settings, on CPU (a ConfigError for sizes
    torch refuses, e.g. a hidden layer of -5 units).

    Only these: a whole D4PGLearner would allocate its replay and set torch's threads, seed and
    denormal mode in this (driver) process.
    """
    features = critic_features(d4pg.critic_features, obs_dim, act_dim)  # its own ConfigError
    try:
        policy = Policy(obs_dim, act_dim, d4pg.policy_hidden, d4pg.layer_norm)
        critic = DistributionalCritic(
            obs_dim, act_dim, d4pg.critic_hidden, d4pg.num_atoms, d4pg.layer_norm, features
        )
    except (RuntimeError, ValueError, TypeError) as exc:
        raise ConfigError(
            f"d4pg: no networks of policy_hidden={quote(d4pg.policy_hidden)}, "
            f"critic_hidden={quote(d4pg.critic_hidden)}: {clip_text(str(exc), 200)}"
        ) from None
    try:
        for net in (policy, critic):
            net.set_action_box(d4pg.action_box_low, d4pg.action_box_high)
    except ValueError as exc:  # a box for another number of action dimensions
        raise ConfigError(f"d4pg.action_box_low/high: {exc}") from None
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


@dataclass(frozen=True)
class RunPlace:
    """Where a run's files go, resolved once before anything starts (``run_place``) and handed
    to the builder: nothing below resolves the name or the root again (a default name is the
    time: resolved twice, it could name two folders)."""

    name: str
    root: RunStorage
    """``--storage`` (else ``--logdir``) as every node sees it (``storage_root``)."""

    @property
    def storage(self) -> RunStorage:
        """The run's own folder: ``<root>/<name>``."""
        return self.root.child(self.name)


def run_place(cfg: TrainConfig, env_id: str, words: Words = FLAGS) -> RunPlace:
    """The run's place: ``cfg.run_name`` (or a new one, ``new_run_name``) under its storage
    root, checked as ``check_run_place`` checks it."""
    root = RunStorage(storage_root(cfg))
    place = RunPlace(cfg.run_name or new_run_name(root, env_id), root)
    check_run_place(place, cfg.resume, env_id, words)
    return place


def new_run_name(root: RunStorage, env_id: str) -> str:
    """The task and the time, with ``-2``, ``-3``... when two runs start in the same second (a
    default name never lands in another run's folder)."""
    base = f"{env_id.split('/')[-1]}-{time.strftime('%Y%m%d-%H%M%S')}"
    name, n = base, 1
    while root.child(name).holds_run() or (root.is_local and (root.path / name).exists()):
        n += 1
        name = f"{base}-{n}"
    return name


def check_run_place(place: RunPlace, resume: bool, env_id: str, words: Words = FLAGS) -> None:
    """A run folder that holds a run already is continued only when asked (``--resume``), and
    only for the same task; ``--resume`` needs a checkpoint to continue from. One line each,
    naming the settings in ``words``."""
    storage = place.storage
    held = storage.holds_run()
    resuming, run_name = words.setting("resume", True), words.name("run_name")
    if held and not resume:
        raise ConfigError(
            f"run folder {storage.location()} holds a run already: pass {resuming} to continue "
            f"it, or another {run_name} (leave it out for a new name each run)"
        )
    if not resume:
        return
    if not storage.exists(RUN_CHECKPOINT):
        raise ConfigError(f"{resuming}: {storage.location()} has no checkpoint to continue from")
    if storage.exists("config.json"):
        try:
            task = json.loads(storage.read_bytes("config.json"))["train"]["task"]
            earlier = resolve_task(task).env_id
        except (ValueError, KeyError, TypeError, ConfigError):
            return  # an unreadable record: the checkpoint's own check (shapes) still applies
        if earlier != env_id:
            raise ConfigError(
                f"{resuming}: {storage.location()} is a run of {earlier}, not {env_id}; pass "
                f"another {run_name} for a new run"
            )


def storage_root(cfg: TrainConfig) -> str:
    """Where the run's folder goes: ``--storage`` (else ``--logdir``), as every node sees it
    (``storage.resolve_root``: absolute, out of a Ray job's temporary working-dir copy)."""
    return resolve_root(cfg.storage or cfg.logdir)
