"""D4PG hyperparameters: one frozen dataclass shared by the local runner and the Ray program.

Choosing the critic's support ``[v_min, v_max]``: the categorical critic can only represent
discounted returns inside it, and atoms outside the real range are wasted resolution.

* effective horizon ``H = 1 / (1 - discount)`` (100 steps for 0.99), capped by the episode
  length when episodes are shorter;
* ``v_max ~ max_reward_per_step * H`` and ``v_min ~ min_reward_per_step * H``;
* for symmetric rewards use ``v_min = -v_max``; for one-signed rewards cover only that sign
  (Pendulum-v1: rewards in [-16.3, 0], so ``[-1500, 0]``; Acme's ±150 would clip almost every
  target there). Alternatively scale rewards in the environment and keep a small support.

Defaults follow DeepMind Acme's D4PG (n-step 5, 51 atoms, batch 256, hard target copies every
100 learner steps, global-norm clipping at 40), except that replay is prioritized (Ape-X).
Target networks: hard copies by default (``target_tau = 0``); set ``target_tau > 0`` for Polyak
averaging every step (the Pendulum-v1 preset in ``training.local`` uses 0.005, as TD3 does).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from robogym_ray.config import check_ranges

COMPILE_MODES = ("", "default", "reduce-overhead", "max-autotune")


@dataclass(frozen=True)
class D4PGConfig:
    """All D4PG hyperparameters; each component reads only the fields it needs."""

    # --- networks -------------------------------------------------------------------------
    policy_hidden: tuple[int, ...] = (400, 300)
    """Hidden layer sizes of the deterministic tanh policy."""
    critic_hidden: tuple[int, ...] = (400, 300)
    """Hidden layer sizes of the distributional critic (input: concatenated obs and action)."""
    layer_norm: bool = False
    """Put a LayerNorm after every hidden Linear (Acme-style); helps with unscaled inputs."""
    critic_features: str = ""
    """Inputs the critic computes from each observation and action beside them
    (``learner/features.py``): '' none; 'ur10e-deploy-pose' the deploy reach's pose errors of
    the wrist where the joints are and where the action sends them. The policy does not see
    them: it stays ``obs -> action``, and so does every file it is exported to."""
    num_atoms: int = 51
    """Number of atoms of the categorical value distribution."""
    v_min: float = -150.0
    """Lowest atom of the support (see the module docstring for how to choose it)."""
    v_max: float = 150.0
    """Highest atom of the support."""

    # --- returns --------------------------------------------------------------------------
    discount: float = 0.99
    """Per-step discount gamma; the n-step target bootstraps with gamma**n."""
    n_step: int = 5
    """Length of the n-step return window computed by the actors."""

    # --- optimisation ---------------------------------------------------------------------
    batch_size: int = 256
    """Transitions per learner step."""
    policy_lr: float = 1e-4
    """Adam learning rate of the policy."""
    critic_lr: float = 1e-4
    """Adam learning rate of the critic."""
    max_grad_norm: float = 40.0
    """Global gradient-norm clip applied to each network separately (0 disables)."""
    target_update_period: int = 100
    """Learner steps between hard copies of the online networks into the targets."""
    target_tau: float = 0.0
    """If > 0, Polyak-average the targets by this much every step instead of hard copies."""
    policy_average_tau: float = 0.0
    """If > 0, also keep a Polyak average of the online policy (moved this fraction of the way
    every learner step); the evaluator scores it, checkpoints store it as ``nets.policy_average``
    and ``evaluate`` / ``export`` use it by default. The workers still act with the online
    policy. It damps the greedy policy's snapshot-to-snapshot swings (docs/results-log.md)."""
    lr_decay_start: int = 0
    """Learner step at which both learning rates start to decay (with ``lr_decay_steps > 0``)."""
    lr_decay_steps: int = 0
    """Learner steps over which both learning rates fall linearly from their base values to
    ``lr_final_scale`` times them (held there afterwards); 0 keeps them constant. Counted in
    learner steps, not wall time, so a schedule replays identically and survives a restore."""
    lr_final_scale: float = 1.0
    """Fraction of the base learning rates reached at the end of the decay, in (0, 1]."""
    policy_smoothness: float = 0.0
    """If > 0, the policy's loss adds this weight times its squared change across each replayed
    n-step window, ``|pi(s_t) - pi(s_t+n)|^2`` summed over the action's [-1, 1] scale (CAPS's
    temporal term, Mysore et al. 2021, over the window the replay holds). A policy of absolute
    targets that tracks a command outputs about the same target from step to step and pays
    little; one that alternates its targets at rest pays for each swing. With an even
    ``n_step`` a two-step alternation goes unseen: use an odd one. 0 (the default): DPG alone."""
    samples_per_insert: float = 32.0
    """Replayed samples per inserted transition; batch_size / this = learner steps per insert."""

    # --- prioritized replay ---------------------------------------------------------------
    replay_capacity: int = 1_000_000
    """Transitions kept; the oldest are evicted first (FIFO) once full."""
    min_replay_size: int = 1_000
    """Transitions required before the first learner step."""
    prioritized: bool = True
    """Proportional prioritized replay; False samples uniformly (weights all 1)."""
    priority_exponent: float = 0.6
    """alpha: P(i) is proportional to p_i**alpha."""
    importance_beta_start: float = 0.4
    """beta at the first learner step; annealed linearly to 1."""
    importance_beta_steps: int = 100_000
    """Learner steps over which beta reaches 1."""
    priority_eps: float = 1e-6
    """Added to every priority so that no transition becomes unsampleable."""

    # --- exploration ----------------------------------------------------------------------
    sigma: float = 0.3
    """Std of the Gaussian exploration noise on the [-1, 1] action scale (per actor); with an
    action box, on the box's own [-1, 1] scale."""
    action_box_low: tuple[float, ...] = ()
    """With ``action_box_high``: the part of the env's action Box the learner works in, one
    bound per action dimension on the [-1, 1] scale that maps onto the whole Box (empty: all
    of it). The policy's tanh spans only this part, the critic reads actions rescaled from it
    and the workers' noise is scaled to it, so a task whose useful actions fill a small part of
    a wide Box gets that part's resolution. The networks carry it (``networks.ActionBox``):
    checkpoints, ``evaluate`` and ``export`` need nothing more, and the env's spaces stay."""
    action_box_high: tuple[float, ...] = ()
    """The upper bounds of ``action_box_low``'s box (same length, each above its low)."""

    # --- runtime --------------------------------------------------------------------------
    device: str = "auto"
    """Learner device: 'auto' picks CUDA when present, else CPU; or any torch device string."""
    num_threads: int = 0
    """torch intra-op threads for the learner; 0 = the CPUs Ray gives the learner actor (its
    ``--learner-cpus``, at least 1), or torch's default outside Ray."""
    replay_device: str = "auto"
    """Where the replay and its priorities live: 'host' (NumPy in memory, segment trees),
    'learner' (torch tensors on the learner's device, flat: sampling without a host round trip),
    or 'auto' (the device when it is not the CPU). Both sample the same transitions for one
    seed, up to float64 round-off at a boundary between two slots."""
    sgd_steps_per_sample: int = 1
    """Learner steps taken from one sampled block of this many batches (Acme's
    ``num_sgd_steps_per_step``); priorities written in a block apply from the next one. 1 samples
    before every step."""
    compile: str = ""
    """torch.compile mode for the loss computations ('default', 'reduce-overhead' (CUDA graphs
    on a GPU), 'max-autotune'); empty: not compiled. The first steps pay the compilation."""
    bf16: bool = False
    """Run the networks under bf16 autocast (the losses and the optimizer stay float32)."""
    whole_step: str = "auto"
    """'on': every learner step reads no host value (device draws, schedules and counters on
    the learner's device, the replay there too) and a GPU replays each block of steps as one
    CUDA graph (a CPU runs the same steps eagerly); 'off': the host-stepped loop; 'auto' (the
    default): 'on' on CUDA when ``compile`` is empty, where an H100 took 5-7x the compiled
    step's updates/s (docs/benchmarks.md 16), 'off' on a CPU, where it gains nothing. For one
    seed it samples other transitions than 'off' (torch's generator, not NumPy's); given the
    same draws, the same steps."""
    rate_tolerance: int = 0
    """0: the learner takes its steps inside the call that inserted the transitions paying for
    them. T > 0 (at least ``sgd_steps_per_sample``): a learner thread steps between inserts, up
    to T steps ahead of the samples-per-insert ratio, and an insert waits while more than T
    steps are owed - the run keeps its ratio within T steps (Reverb's error buffer)."""

    def __post_init__(self) -> None:
        checks = [
            (self.num_atoms >= 2, "num_atoms", self.num_atoms, ">= 2"),
            (self.v_min < self.v_max, "v_min", (self.v_min, self.v_max), "v_min < v_max"),
            (0.0 < self.discount <= 1.0, "discount", self.discount, "in (0, 1]"),
            (self.n_step >= 1, "n_step", self.n_step, ">= 1"),
            (self.batch_size >= 1, "batch_size", self.batch_size, ">= 1"),
            (0.0 <= self.target_tau <= 1.0, "target_tau", self.target_tau, "in [0, 1]"),
            (
                0.0 <= self.policy_average_tau < 1.0,
                "policy_average_tau",
                self.policy_average_tau,
                "in [0, 1)",
            ),
            (
                self.target_update_period >= 1,
                "target_update_period",
                self.target_update_period,
                ">= 1",
            ),
            (self.lr_decay_start >= 0, "lr_decay_start", self.lr_decay_start, ">= 0"),
            (self.lr_decay_steps >= 0, "lr_decay_steps", self.lr_decay_steps, ">= 0"),
            (0.0 < self.lr_final_scale <= 1.0, "lr_final_scale", self.lr_final_scale, "in (0, 1]"),
            (
                0.0 <= self.policy_smoothness < math.inf,
                "policy_smoothness",
                self.policy_smoothness,
                ">= 0 and finite",
            ),
            (self.samples_per_insert > 0, "samples_per_insert", self.samples_per_insert, "> 0"),
            (
                self.replay_capacity >= self.batch_size,
                "replay_capacity",
                self.replay_capacity,
                ">= batch_size",
            ),
            (self.priority_exponent >= 0.0, "priority_exponent", self.priority_exponent, ">= 0"),
            (
                0.0 <= self.importance_beta_start <= 1.0,
                "importance_beta_start",
                self.importance_beta_start,
                "in [0, 1]",
            ),
            (self.sigma >= 0.0, "sigma", self.sigma, ">= 0"),
            (
                len(self.action_box_low) == len(self.action_box_high)
                and all(
                    -1.0 <= lo < hi <= 1.0
                    for lo, hi in zip(self.action_box_low, self.action_box_high, strict=False)
                ),
                "action_box_low",
                (self.action_box_low, self.action_box_high),
                "low and high of equal length, -1 <= low < high <= 1 in each dimension",
            ),
            (self.num_threads >= 0, "num_threads", self.num_threads, ">= 0"),
            (
                self.replay_device in ("auto", "host", "learner"),
                "replay_device",
                self.replay_device,
                "'auto', 'host' or 'learner'",
            ),
            (
                self.sgd_steps_per_sample >= 1,
                "sgd_steps_per_sample",
                self.sgd_steps_per_sample,
                ">= 1",
            ),
            (
                self.rate_tolerance == 0 or self.rate_tolerance >= self.sgd_steps_per_sample,
                "rate_tolerance",
                self.rate_tolerance,
                "0 (coupled) or >= sgd_steps_per_sample",
            ),
            (
                self.whole_step in ("on", "off", "auto"),
                "whole_step",
                self.whole_step,
                "'on', 'off' or 'auto'",
            ),
            (
                not (self.whole_step == "on" and self.compile),
                "whole_step",
                (self.whole_step, self.compile),
                "'on' with compile '' (the whole step is its own CUDA graph)",
            ),
            (
                not (self.whole_step == "on" and self.replay_device == "host"),
                "whole_step",
                (self.whole_step, self.replay_device),
                "'on' with the replay on the learner's device (replay_device 'auto' or 'learner')",
            ),
            (
                self.compile in COMPILE_MODES,
                "compile",
                self.compile,
                " or ".join(repr(m) for m in COMPILE_MODES),
            ),
        ]
        check_ranges("D4PGConfig", checks)
