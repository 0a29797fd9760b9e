"""Final evaluations (the paper's table): N greedy episodes of a trained policy.

The policy is a learner checkpoint or an exported TorchScript file (``robogym_ray.export``); the
env is a registered id with its own simulated server, or a running robot server given by
address (a real robot or ``robogym-ray serve --real-time --emulate-hardware``), driven through
the task's ``Rob`` variant (``variant="rob"``, the real-robot contract: no sim-only checks, the
MiR100 starts where it stands) or its ``Sim`` variant pinned to that server (``variant="sim"``:
resets place robot and obstacles as in training, as an operator would). With ``via_actor`` the
Rob env goes through a real-robot actor (safety filter, pause on errors) as in training.

Result: counts and rates of success / collision / timeout (anything else is ``other``) and, per
episode, the seed, final status, return, length and target (the UR figure plots the targets).
"""

from __future__ import annotations

import argparse
import contextlib
import json
import time
from collections import Counter
from collections.abc import Callable, Iterator, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from robogym_ray.config import check_address, check_dir_path, quote
from robogym_ray.envs import outcomes
from robogym_ray.envs.frames import QUAT_ORDERS
from robogym_ray.envs.outcomes import CATEGORIES
from robogym_ray.envs.registration import server_spec_of, variant_id
from robogym_ray.envs.render.video import EpisodeVideos
from robogym_ray.errors import ConfigError
from robogym_ray.experience.episodes import greedy_episode
from robogym_ray.protocol.tls import read_ca
from robogym_ray.robots.serve import serve_process


@dataclass(frozen=True)
class EvaluationConfig:
    """What ``robogym-ray evaluate`` runs."""

    env_id: str | None = None
    """Env id (Sim or Rob; either picks the task); default: the policy's own (sidecar or run)."""
    rs_address: str | None = None
    """HOST:PORT of a running robot server (real or emulated); default: a simulated one."""
    variant: str = "rob"
    """With --rs-address: 'rob' (real-robot contract) or 'sim' (sim resets on that server)."""
    episodes: int = 100
    """Episodes to run."""
    seed: int = 1000
    """Episode i resets with seed + i."""
    max_steps: int | None = None
    """Episode step limit (default: the task's)."""
    token: str | None = None
    """Shared token of the robot server, if it wants one."""
    tls_ca: str | None = None
    """PEM file of the CA that signed the robot server's TLS certificate (its serve
    --tls-cert); the server is verified against it. Default: a plain connection."""
    via_actor: bool = False
    """Drive the robot server through a real-robot actor on a local Ray (safety filter)."""
    online_weights: bool = False
    """Evaluate a learner.pt's online policy even when the run kept a Polyak-averaged one
    (policy_average_tau > 0), which is evaluated by default."""
    out: str | None = None
    """Directory for evaluation.json and evaluation.md (default: print only)."""
    video: str | None = None
    """Directory for an MP4 of each of the first --video-episodes episodes (named by index,
    seed and outcome); needs the video extra."""
    video_episodes: int = 3
    """How many episodes --video films (the first ones)."""
    paths: bool = False
    """Record each episode's robot positions (MiR100: x, y; UR: tool0) in evaluation.json, for
    experiments/figures.py's path plots."""
    isaac_lab: bool = False
    """The policy is an Isaac Lab export (rsl_rl play.py's policy.pt, TorchScript, or
    policy.onnx): raw observations in, raw actions in the env's units out; needs --env-id."""
    io_descriptors: str | None = None
    """With --isaac-lab: Isaac Lab 3's IO descriptors of the policy (export_IODescriptors.py
    writes <task>_IO_descriptors.yaml), checked against the env before the first action; its
    action term's scale, offset and clip are applied."""
    ema_alpha: float = 1.0
    """With --isaac-lab: Isaac ROS's action filter, a = alpha x clamped + (1 - alpha) x the
    last a, in (0, 1]; 1.0 (Isaac ROS's default) is none."""
    quat_order: str | None = None
    """With --isaac-lab on a deploy-reach env: the command quaternion's order the policy was
    trained with, xyzw (Isaac Lab 3, the default) or wxyz (Isaac Lab 2.x, Isaac ROS); the IO
    descriptors do not say it."""

    def __post_init__(self) -> None:
        if self.variant not in ("rob", "sim"):
            raise ConfigError(f"variant must be 'rob' or 'sim', got {self.variant!r}")
        if self.episodes < 1:
            raise ConfigError(f"episodes must be >= 1, got {self.episodes}")
        if self.video_episodes < 1:
            raise ConfigError(f"video_episodes must be >= 1, got {self.video_episodes}")
        if self.tls_ca is not None and self.rs_address is None:
            raise ConfigError("--tls-ca is for a robot server at --rs-address: add it")
        if self.via_actor and (self.rs_address is None or self.variant != "rob"):
            raise ConfigError("via_actor needs --rs-address and --variant rob")
        for flag, given in (("--io-descriptors", self.io_descriptors is not None),
                            ("--ema-alpha", self.ema_alpha != 1.0),
                            ("--quat-order", self.quat_order is not None)):  # fmt: skip
            if given and not self.isaac_lab:
                raise ConfigError(f"{flag} is for an Isaac Lab policy: add --isaac-lab")
        if not 0.0 < self.ema_alpha <= 1.0:
            raise ConfigError(f"ema_alpha must be in (0, 1], got {self.ema_alpha}")
        if self.quat_order not in (None, *QUAT_ORDERS):
            raise ConfigError(f"quat_order must be one of {QUAT_ORDERS}, got {self.quat_order!r}")
        if self.isaac_lab and self.env_id is None:
            raise ConfigError("--isaac-lab needs --env-id: an Isaac Lab policy file names no env")
        if self.rs_address is not None:
            check_address(self.rs_address, "--rs-address")
        for flag, where in (("--out", self.out), ("--video", self.video)):
            if where is not None:
                check_dir_path(where, flag)


@dataclass(frozen=True)
class EpisodeRecord:
    index: int
    seed: int
    final_status: str
    ret: float
    length: int
    target: list[float] | None
    """The episode's target (MiR100: x, y, yaw; UR: x, y, z in base_link), if the task has one."""
    path: list[list[float]] | None = None
    """The robot's positions after reset and after each step (``--paths``), else None."""
    obstacles: list[list[float]] | None = None
    """With ``--paths``, the cubes the episode placed (MiR100: x, y, yaw each), if any."""
    position_error: float | None = None
    """The end effector's final distance to its target (m), for tasks that report it."""
    rotation_error: float | None = None
    """Its final rotation error (rad), for tasks whose target has an orientation."""
    window_errors: list[list[float]] | None = None
    """(position, rotation) at the end of each command window, for tasks that have them."""

    def to_dict(self) -> dict[str, Any]:
        record = asdict(self)
        # evaluation.json stays as it was for tasks and runs without these
        for key in ("path", "obstacles", "position_error", "rotation_error", "window_errors"):
            if record[key] is None:
                del record[key]
        return record


@dataclass
class EvaluationResult:
    env_id: str
    rs_address: str | None
    policy: str
    episodes: list[EpisodeRecord] = field(default_factory=list)
    wall_s: float = 0.0

    @property
    def counts(self) -> dict[str, int]:
        return outcomes.counts(e.final_status for e in self.episodes)

    @property
    def rates(self) -> dict[str, float]:
        return outcomes.rates(e.final_status for e in self.episodes)

    def summary(self) -> dict[str, Any]:
        returns = [e.ret for e in self.episodes]
        means = {k: _mean_of(self.episodes, k) for k in ("position_error", "rotation_error")}
        return {
            "env_id": self.env_id, "rs_address": self.rs_address, "policy": self.policy,
            "n_episodes": len(self.episodes), "counts": self.counts, "rates": self.rates,
            "statuses": dict(Counter(e.final_status for e in self.episodes)),
            "mean_return": float(np.mean(returns)) if returns else 0.0,
            "mean_length": float(np.mean([e.length for e in self.episodes] or [0])),
            **{f"mean_{k}": v for k, v in means.items() if v is not None},
            **self.measures(),
            "wall_s": round(self.wall_s, 2),
        }  # fmt: skip

    def measures(self) -> dict[str, float]:
        """The task's own measures, medians over what it reports: the window-end errors of a
        task with command windows, else the final errors (none for tasks without either)."""
        windows = outcomes.window_medians(w for e in self.episodes for w in e.window_errors or [])
        if windows:
            return {f"median_{k}": round(v, 5) for k, v in windows.items()}
        found = {k: [getattr(e, k) for e in self.episodes if getattr(e, k) is not None]
                 for k in ("position_error", "rotation_error")}  # fmt: skip
        return {f"median_{k}": round(float(np.median(v)), 5) for k, v in found.items() if v}

    def to_dict(self) -> dict[str, Any]:
        return {**self.summary(), "episodes": [e.to_dict() for e in self.episodes]}

    def to_markdown(self) -> str:
        s, n = self.summary(), len(self.episodes)
        cells = [f"{s['counts'][c]} ({100 * s['rates'][c + '_rate']:.0f} %)" for c in CATEGORIES]
        where = self.rs_address or "simulation"
        head = ["env", "robot server", "episodes", *CATEGORIES, "mean return"]
        row = [self.env_id, where, str(n), *cells, f"{s['mean_return']:.1f}"]
        for key, value in self.measures().items():  # the task's own, where it has any
            head.append(f"{key.replace('_', ' ')} ({'rad' if 'rotation' in key else 'm'})")
            row.append(f"{value:.4f}")
        lines = [head, ["---"] * len(head), row]
        return "\n".join("| " + " | ".join(line) + " |" for line in lines)


def _mean_of(episodes: list[EpisodeRecord], attr: str) -> float | None:
    values = [getattr(e, attr) for e in episodes if getattr(e, attr) is not None]
    return round(float(np.mean(values)), 5) if values else None


def serve_args(env_id: str) -> list[str]:
    """``robogym-ray serve`` arguments for the robot server a task needs: its
    ``server_spec_of`` (robot, scene, options) as flags.

    Add ``--real-time --emulate-hardware`` for the emulated real robot of that task.
    """
    # Through the Sim id: a non-RoboGymRay id fails here, in variant_id's one line.
    robot, scene, options = server_spec_of(variant_id(env_id, "sim"))
    args = ["--robot", robot] + (["--scene", scene] if scene else [])
    if options:
        args += ["--option", *(f"{k}={v}" for k, v in options.items())]
    return args


@contextlib.contextmanager
def emulated_server(
    env_id: str, seed: int | None = None, extra: Sequence[str] = (), real_time: bool = True
) -> Iterator[str]:
    """``robogym-ray serve --emulate-hardware`` for ``env_id``'s robot in a child process.

    Yields its address; the process is stopped (SIGTERM) on exit. ``extra``: more serve flags,
    e.g. ``["--emu-latency-ticks", "2"]``.
    """
    args = ["--emulate-hardware", *(["--real-time"] if real_time else []), *serve_args(env_id),
            *(["--seed", str(seed)] if seed is not None else []), *extra]  # fmt: skip
    with serve_process(args) as address:
        yield address


def report(result: EvaluationResult, out: str | None) -> None:
    """Write ``evaluation.json``/``.md`` to ``out`` (if given) and print the table and JSON."""
    if out:
        write_result(result, out)
    print(result.to_markdown())
    print(json.dumps(result.summary()), flush=True)


def run_episodes(
    policy: Callable[[np.ndarray], np.ndarray],
    env: Any,
    episodes: int,
    seed: int,
    videos: EpisodeVideos | None = None,
    paths: bool = False,
) -> Iterator[EpisodeRecord]:
    """Greedy episodes; ``policy`` maps an observation to an action in [-1, 1].

    ``videos`` films the episodes it wants (the env renders ``rgb_array``); ``paths`` keeps the
    robot's positions (``env.unwrapped.position()``) and the cubes placed in each record.
    """
    for i in range(episodes):
        filmed = videos is not None and videos.wants(i)
        ep = greedy_episode(env, policy, seed + i, film=filmed, track=paths)
        if filmed:
            assert videos is not None
            videos.save(i, seed + i, ep.final_status, ep.frames)
        yield EpisodeRecord(
            i, seed + i, ep.final_status, ep.ret, ep.length, ep.target, ep.path, ep.obstacles,
            ep.position_error, ep.rotation_error, ep.window_errors,
        )  # fmt: skip


def evaluate(policy_path: str | Path, cfg: EvaluationConfig) -> EvaluationResult:
    """Run ``cfg.episodes`` episodes of the policy at ``policy_path`` (see the module docstring)."""
    import gymnasium as gym

    import robogym_ray.envs  # noqa: F401 - registers the ids
    from robogym_ray.export import load_policy, sidecar_path
    from robogym_ray.storage import local_file

    tls_ca = read_ca(cfg.tls_ca)  # one line naming the file, before the policy is loaded
    policy_path = local_file(policy_path, "policy")  # an object store's: downloaded once
    if cfg.isaac_lab:
        from robogym_ray.isaac_lab import IsaacLabPolicy

        # read and checked before any env or Ray
        policy: Any = IsaacLabPolicy(policy_path, cfg.io_descriptors)
        label, env_id, dims = str(policy_path), cfg.env_id, (policy.obs_dim, policy.act_dim)
    else:
        policy = load_policy(policy_path, cfg.online_weights)
        # A checkpoint's label says which of its policies ran (PATH#policy_average).
        exported = sidecar_path(policy_path).exists()
        label = str(policy_path) if exported else str(policy.info.source)
        env_id, dims = cfg.env_id or policy.info.env_id, (policy.info.obs_dim, policy.info.act_dim)
    if env_id is None:
        raise ConfigError(f"no env id known for {policy_path}: pass --env-id")
    kwargs: dict[str, Any] = {"token": cfg.token}
    if cfg.max_steps is not None:
        kwargs["max_steps"] = cfg.max_steps
    if cfg.quat_order is not None:
        kwargs["isaac_quat_order"] = cfg.quat_order
    if cfg.rs_address:
        env_id = variant_id(env_id, cfg.variant)
        kwargs["rs_address"] = cfg.rs_address
        kwargs["tls_ca"] = tls_ca
    else:
        env_id = variant_id(env_id, "sim")
    try:
        gym.spec(env_id)  # before --via-actor starts Ray
    except gym.error.Error as exc:  # an id of the right form that no task has
        raise ConfigError(f"env id {quote(env_id)}: {str(exc).splitlines()[0]}") from None
    with contextlib.ExitStack() as stack:
        if cfg.via_actor:
            assert cfg.rs_address is not None
            from robogym_ray.distributed.real_client import real_robot_actor  # imports Ray

            kwargs["client_factory"] = stack.enter_context(
                real_robot_actor(env_id, cfg.rs_address, cfg.token, tls_ca)
            )
        videos = None
        if cfg.video:
            kwargs["render_mode"] = "rgb_array"
        try:
            env = gym.make(env_id, **kwargs)
        except TypeError as exc:  # the one keyword an env may not take
            if "isaac_quat_order" not in str(exc):
                raise
            raise ConfigError(f"--quat-order: {env_id} observes no Isaac Lab command") from None
        stack.callback(env.close)
        if cfg.video:
            fps = env.metadata["render_fps"]
            videos = EpisodeVideos(cfg.video, min(cfg.video_episodes, cfg.episodes), fps)
        _check_dims(env, *dims, env_id)
        if cfg.isaac_lab:  # behind Isaac ROS's decoder (IO descriptors: checked first)
            policy = policy.unit_policy(env, cfg.ema_alpha)
        result = EvaluationResult(env_id, cfg.rs_address, label)
        start = time.perf_counter()
        result.episodes = list(run_episodes(policy, env, cfg.episodes, cfg.seed, videos, cfg.paths))
        result.wall_s = time.perf_counter() - start
    return result


def _check_dims(env: Any, obs_dim: int, act_dim: int, env_id: str) -> None:
    got = (env.observation_space.shape[0], env.action_space.shape[0])
    if got != (obs_dim, act_dim):
        raise ConfigError(
            f"the policy maps {obs_dim} observations to {act_dim} actions; {env_id} has "
            f"{got[0]} and {got[1]}"
        )


def write_result(result: EvaluationResult, out: str | Path) -> tuple[Path, Path]:
    """``out/evaluation.json`` (summary and episodes) and ``out/evaluation.md`` (the table)."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    json_path, md_path = out / "evaluation.json", out / "evaluation.md"
    json_path.write_text(json.dumps(result.to_dict(), indent=2))
    md_path.write_text(result.to_markdown() + "\n")
    return json_path, md_path


# -- CLI: robogym-ray evaluate -----------------------------------------------------------------
def add_arguments(parser: argparse.ArgumentParser) -> None:
    from robogym_ray.config import add_config_args

    parser.add_argument(
        "policy",
        help="A run's folder (its checkpoint is taken), a learner.pt checkpoint or an exported "
        "policy (with .json).",
    )
    add_config_args(parser, EvaluationConfig)


def run(args: argparse.Namespace) -> int:
    from robogym_ray.config import config_from_args
    from robogym_ray.export import policy_argument

    cfg = config_from_args(EvaluationConfig, args)
    result = evaluate(policy_argument(args.policy), cfg)
    report(result, cfg.out)
    return 0
