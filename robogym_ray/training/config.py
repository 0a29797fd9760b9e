"""``TrainConfig``: what ``robogym-ray train`` runs (D4PG hyperparameters are separate)."""

from __future__ import annotations

from dataclasses import dataclass

from robogym_ray.config import check_ranges, is_address, is_ray_address

SIM_PATHS = ("inprocess", "grpc")
DEFAULT_TOTAL_STEPS = 3000
"""A run's env steps when it is given neither ``total_steps`` nor ``max_wall_s``."""


@dataclass(frozen=True)
class TrainConfig:
    """One distributed D4PG run."""

    task: str = "navigation"
    """A task's short name (navigation, positioning, pendulum, ...) or an env id (e.g.
    RoboGymRay/ObstacleAvoidanceMir100Sim-v0): `robogym-ray tasks` lists them all."""
    workers: int = 2
    """Simulated rollout workers (each steps --envs-per-worker simulated robots)."""
    envs_per_worker: int = 4
    """Envs each simulated worker steps together, with one batched policy forward per round
    (real-robot workers always have one)."""
    sim_path: str = "inprocess"
    """Where simulated robots run. inprocess (default, fast): inside their worker's process,
    called directly, faults rebuilt and counted by the worker. grpc: each env talks to its own
    supervised robot-server actor over robo-gym's gRPC protocol (robot servers on other nodes,
    --server-resource, a wire identical to a real robot's)."""
    worker_deadline_s: float = 120.0
    """A simulated worker's call that has not returned after this many seconds (a simulation
    stuck in a physics step) gets the worker killed and replaced, counted as a hung restart."""
    emulated_workers: int = 0
    """How many of the simulated workers train on emulated robots (sensor noise, actuation
    latency, dynamics differences: the --emu-* settings or the config file's "emulation"
    section) instead of the plain simulation - domain randomisation for policies meant for
    real hardware. The first N workers (the most exploratory) get them; the evaluator stays on
    the plain simulation."""
    real_robot: tuple[str, ...] = ()
    """HOST:PORT of real robot servers; each adds a rollout worker on the task's Rob variant."""
    token: str | None = None
    """Shared token of the --real-robot servers (their `serve --token`); default: the
    ROBOGYM_RAY_TOKEN environment variable. Never written to config.json."""
    tls_ca: str | None = None
    """PEM file of the CA that signed the --real-robot servers' TLS certificates (their serve
    --tls-cert); read on this machine, so no other node needs it. Default: plain connections."""
    real_robot_wait_s: float = 60.0
    """Once total_steps are collected (or max_wall_s has passed), how long to wait for
    real-robot calls still running; a call that has not returned by then (a paused robot
    waits for an operator) is abandoned, counted, and its steps are not collected."""
    total_steps: int | None = None
    """Env steps to collect over all workers (default: 3000; none when --max-wall-s is given
    alone: a run given a time runs for that time)."""
    max_wall_s: float | None = None
    """Stop collecting after this many seconds of training, even before total_steps; given
    without --total-steps, the time alone ends the run."""
    logdir: str = "runs"
    """Where runs' files go when --storage is not given (a path; made absolute here)."""
    storage: str | None = None
    """Where every file of the run goes, under STORAGE/RUN_NAME/, from whichever node writes
    it: a path (in a multi-node run, one every node mounts, e.g. NFS: a node-local path is
    refused before anything starts) or an object store URI (s3://bucket/prefix, gs://...;
    an S3-compatible server via ?endpoint_override=HOST:PORT&scheme=http or AWS_ENDPOINT_URL).
    A relative path in a submitted Ray job goes under ~/robogym_ray_results on the head.
    Default: --logdir."""
    run_name: str | None = None
    """Run folder name; one that holds a run already is refused unless --resume (default: the
    task and the time, never an existing one)."""
    resume: bool = False
    """Continue the run in STORAGE/RUN_NAME from its checkpoint (same task and networks: checked
    before Ray starts) instead of refusing a run name that is taken."""
    seed: int = 0
    """Seed of worker i is seed + i; the learner uses seed."""
    address: str | None = None
    """Ray address: None starts a local Ray (embedded); 'auto' joins a running cluster."""
    config: str | None = None
    """JSON file {"train": {...}, "d4pg": {...}, "emulation": {...}}, optionally "extends":
    "base.json" (its fields override the base's); command-line flags win over its train part."""
    num_cpus: float | None = None
    """CPUs of the embedded local Ray (default: all of this machine)."""
    steps_per_call: int = 50
    """Env steps a worker runs per round trip to the driver."""
    weight_sync_steps: int = 200
    """A worker pulls new weights after this many of its own env steps."""
    random_steps: int = 500
    """Each worker's first env steps use uniform random actions."""
    sigma_min: float = 0.1
    """Exploration noise of the last worker; worker sigmas spread from d4pg.sigma down to it."""
    sigma_decay_start: int = 0
    """Env steps (all workers together, counted from this run's start: an --init-from run starts
    again at 0) after which every worker's exploration noise starts to shrink, when
    sigma_decay_steps > 0."""
    sigma_decay_steps: int = 0
    """Env steps over which each worker's sigma falls linearly to sigma_final_scale times its
    start (the spread between workers is kept); 0 = constant noise. Late in a run the replay
    then holds more of the states the greedy policy visits."""
    sigma_final_scale: float = 1.0
    """Fraction of each worker's sigma left once the decay is over, in [0, 1]."""
    revisit_failed: float = 0.0
    """Chance, in [0, 1], that a simulated worker's reset re-runs the start (same reset seed:
    same start, goal and obstacles) of an episode it failed recently; 0 = off. See
    robogym_ray/experience/revisits.py."""
    revisit_pool: int = 64
    """Failed starts each worker keeps for revisits (the oldest is forgotten first)."""
    revisit_max: int = 2
    """Times one failed start is re-run at most (a revisit that succeeds retires it at once)."""
    relabel_goals: int = 0
    """Copies of each step under commands its episode reached later (HER); 0 = off. Goal
    tasks only; samples_per_insert counts the copies (experience/relabel.py)."""
    checkpoint_every: int = 500
    """Learner steps between checkpoints (a restarted learner resumes from the latest)."""
    init_from: str | None = None
    """learner.pt of an earlier run to continue from (networks, optimisers, step count, and its
    replay when LEARNER.pt.replay.npz lies beside it); ignored when this run's directory already
    has a checkpoint, which is newer."""
    save_replay: bool = False
    """Write the replay buffer beside the final checkpoint, for a later --init-from."""
    replay_snapshot_every_s: float = 300.0
    """Every this many seconds the learner's checkpoint also writes the replay, so a learner
    that Ray restarts restores it and loses only the transitions inserted since (~186 MB and
    ~1 s a snapshot at 1 M navigation transitions, docs/benchmarks.md). 0 = never: a restarted
    learner starts with an empty replay. summary.json's lost_transitions counts the loss."""
    evaluator: bool = True
    """Run an evaluator actor with the greedy policy on its own env."""
    eval_env_id: str | None = None
    """The evaluator's env (an id or a task name) when not the task's; same spaces, checked.
    eval/* and select_episodes then follow its success, e.g. isaac-reach-ur10 for a run of
    isaac-reach-ur10-isaac-reward. null = the task's env."""
    eval_interval_s: float = 0.0
    """Seconds from the start of one evaluator call to the start of the next (0 = back to
    back). On 2 cores a back-to-back evaluator costs the learner 15-20 percent of its steps
    (docs/benchmarks.md); an interval bounds that share."""
    final_eval_episodes: int = 10
    """Greedy episodes the final policy plays at the end of a run in which the evaluator
    finished none (a short run, or a busy machine), so every run's summary and eval/* have
    rates. A run whose evaluator finished episodes reports its last window instead."""
    video_interval_s: float = 300.0
    """Every this many seconds the evaluator films one greedy episode (320x240, drawn from
    the robot state) into TensorBoard's eval/video, as an animated GIF. 0 = no video."""
    select_episodes: int = 0
    """Snapshot selection: when > 0 the evaluator scores each weights snapshot on the same
    this-many greedy episodes, and the best-scoring one (success rate, then mean return) is
    kept as checkpoints/policy-best.pt (policy only; evaluate and export take it). The
    learner's own final state can be a worse draw: a greedy policy's success rate swings by a
    few points from one snapshot to the next. 0 = one new episode per snapshot, no selection."""
    policy_snapshot_every_s: float = 300.0
    """Every this many wall seconds the policy the evaluator scores (the average, with policy
    averaging) is kept as checkpoints/policy-MMM.MMmin.pt (~0.5 MB each; evaluate and export
    take it), so a run's success against wall time can be scored afterwards on the same fixed
    episodes as any other policy's (experiments/peers.py evaluate). 0 = none."""
    worker_cpus: float = 0.25
    """Ray CPUs reserved per rollout worker (fractional: they mostly wait on their server)."""
    learner_cpus: float = 0.5
    """Ray CPUs reserved for the learner; its torch threads follow them (rounded down, at
    least 1) unless the d4pg section sets num_threads."""
    batch_per_worker: int = 0
    """When > 0, the learner's batch is this many transitions per rollout worker (simulated
    and real), samples_per_insert unchanged: a cluster with more workers trains on larger
    batches, and its learner takes fewer, larger steps per env step (docs/scaling.md). 0: the
    d4pg section's batch_size."""
    server_cpus: float = 0.2
    """Ray CPUs reserved per supervised robot server (--sim-path grpc: one per simulated env,
    one for the evaluator)."""
    evaluator_cpus: float = 0.1
    """Ray CPUs reserved for the evaluator."""
    learner_gpus: float = -1.0
    """GPUs for the learner: -1 = one if the cluster has any, else 0."""
    learner_resource: str | None = None
    """Custom Ray resource the learner requires (e.g. one that only a GPU node has); it is
    restarted only on nodes that have it too."""
    worker_resource: str | None = None
    """Custom Ray resource every rollout worker requires (e.g. the CPU nodes')."""
    spread_workers: bool = True
    """Spread rollout workers over the nodes that fit them (Ray's SPREAD), rather than fill
    one node first."""
    evaluator_resource: str | None = None
    """Custom Ray resource the evaluator requires."""
    server_resource: str | None = None
    """Custom Ray resource the simulations require (places them on the nodes that have it): the
    robot-server actors with --sim-path grpc, the simulated workers with inprocess."""
    log_every_s: float = 5.0
    """Seconds between TensorBoard writes of rates and counters."""
    progress: bool = True
    """Show a progress bar in the terminal."""

    @property
    def rollout_workers(self) -> int:
        """Every rollout worker: the simulated ones and one per real robot."""
        return self.workers + len(self.real_robot)

    def __post_init__(self) -> None:
        if self.total_steps is None and self.max_wall_s is None:
            # Given neither, a short run; given only a time, the time ends it (None stays: no
            # step cap), rather than a default step count the user never asked for.
            object.__setattr__(self, "total_steps", DEFAULT_TOTAL_STEPS)
        checks = [
            (self.workers >= 0, "workers", ">= 0"),
            (self.rollout_workers >= 1, "workers", ">= 1 with no real robot"),
            (
                0 <= self.emulated_workers <= self.workers,
                "emulated_workers",
                f"in [0, workers={self.workers}]",
            ),
            (
                self.total_steps is None or self.total_steps >= 1,
                "total_steps",
                ">= 1 (or null with max_wall_s: no step cap)",
            ),
            (self.steps_per_call >= 1, "steps_per_call", ">= 1"),
            (self.envs_per_worker >= 1, "envs_per_worker", ">= 1"),
            (self.sim_path in SIM_PATHS, "sim_path", f"one of {', '.join(SIM_PATHS)}"),
            (self.worker_deadline_s > 0, "worker_deadline_s", "> 0"),
            (self.select_episodes >= 0, "select_episodes", ">= 0"),
            (self.eval_interval_s >= 0, "eval_interval_s", ">= 0"),
            (self.final_eval_episodes >= 1, "final_eval_episodes", ">= 1"),
            (self.real_robot_wait_s >= 0, "real_robot_wait_s", ">= 0"),
            (self.replay_snapshot_every_s >= 0, "replay_snapshot_every_s", ">= 0"),
            (self.video_interval_s >= 0, "video_interval_s", ">= 0"),
            (
                self.policy_snapshot_every_s == 0 or self.policy_snapshot_every_s >= 1,
                "policy_snapshot_every_s",
                "0 or >= 1 (files are named to 0.01 min)",
            ),
            (self.evaluator or not self.select_episodes, "select_episodes", "0 without evaluator"),
            (self.evaluator or self.eval_env_id is None, "eval_env_id", "null without evaluator"),
            (self.weight_sync_steps >= 1, "weight_sync_steps", ">= 1"),
            (self.sigma_min >= 0, "sigma_min", ">= 0"),
            (self.sigma_decay_start >= 0, "sigma_decay_start", ">= 0"),
            (self.sigma_decay_steps >= 0, "sigma_decay_steps", ">= 0"),
            (0.0 <= self.sigma_final_scale <= 1.0, "sigma_final_scale", "in [0, 1]"),
            (0.0 <= self.revisit_failed <= 1.0, "revisit_failed", "in [0, 1]"),
            (self.revisit_pool >= 1, "revisit_pool", ">= 1"),
            (self.revisit_max >= 1, "revisit_max", ">= 1"),
            (self.relabel_goals >= 0, "relabel_goals", ">= 0"),
            (self.worker_cpus > 0, "worker_cpus", "> 0"),
            (self.learner_cpus > 0, "learner_cpus", "> 0"),
            (self.server_cpus > 0, "server_cpus", "> 0"),
            (self.evaluator_cpus > 0, "evaluator_cpus", "> 0"),
            (self.batch_per_worker >= 0, "batch_per_worker", ">= 0"),
            (self.num_cpus is None or self.num_cpus > 0, "num_cpus", "> 0 or null"),
            (self.max_wall_s is None or self.max_wall_s > 0, "max_wall_s", "> 0 or null"),
            (self.checkpoint_every >= 0, "checkpoint_every", ">= 0 (0 = never)"),
            (self.log_every_s >= 0, "log_every_s", ">= 0"),
            (self.learner_gpus >= -1, "learner_gpus", ">= 0, or -1 for one if there is any"),
            (bool(self.logdir), "logdir", "a directory name"),
            (all(map(is_address, self.real_robot)), "real_robot", "HOST:PORT each (port 1-65535)"),
            (
                self.tls_ca is None or bool(self.real_robot),
                "tls_ca",
                "only with a real robot (the CA is for its server)",
            ),
            (
                self.address is None or is_ray_address(self.address),
                "address",
                "null, auto, HOST:PORT or ray://HOST:PORT",
            ),
        ]
        # FieldErrors: the command line names the flag, a Python call the keyword.
        check_ranges("TrainConfig", ((ok, name, getattr(self, name), expected)
                                     for ok, name, expected in checks))  # fmt: skip
