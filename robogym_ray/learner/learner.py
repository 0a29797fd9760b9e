"""The D4PG learner: owns replay, networks, targets and optimizers; no Ray in here.

Data path: actors insert n-step transitions (with initial priorities, or the running max) via
:meth:`D4PGLearner.add`; :meth:`run` samples prioritized batches, takes a gradient step on
critic and policy per batch and writes the per-sample critic loss back as the new priorities;
:meth:`get_weights` hands the policy to actors as plain CPU arrays.

One code path for every device: on a GPU the replay lives on the device (``replay_device``),
the losses may be compiled (``compile``) and run in bf16 (``bf16``), and a call's metrics come
to the host once; the CPU tests run the same code with the same switches. With ``whole_step``
the steps read no host value at all and a GPU replays each block as one CUDA graph
(``learner/whole_step.py``); a CPU runs the same steps eagerly.
"""

from __future__ import annotations

import contextlib
import copy
import os
from typing import Any

import numpy as np
import torch
from torch import nn

from robogym_ray.learner import checkpoint
from robogym_ray.learner.config import D4PGConfig
from robogym_ray.learner.distributional import (
    categorical_cross_entropy,
    categorical_projection,
    expected_value,
    make_support,
)
from robogym_ray.learner.features import critic_features
from robogym_ray.learner.networks import DistributionalCritic, Policy
from robogym_ray.learner.replay import Backend, PrioritizedReplay
from robogym_ray.learner.schedules import importance_beta, lr_scale
from robogym_ray.learner.whole_step import WholeStep


def pick_device(name: str = "auto") -> torch.device:
    """'auto' -> CUDA when available, else CPU; anything else is passed to torch."""
    if name == "auto":
        return torch.device("cuda" if torch.cuda.is_available() else "cpu")
    return torch.device(name)


def make_adam(params: Any, lr: float, device: torch.device | None = None) -> torch.optim.Adam:
    """Adam with the fused kernel (one kernel for all parameters) where this torch has it.

    With ``device``, the learning rate is a tensor there, which the whole step changes in place,
    and on CUDA the step is capturable in a graph. On a CPU the tensor is float64: the fused
    kernel then takes the updates a Python float rate gives, bit for bit. On CUDA it is float32,
    which the fused kernel reads there, so a rate may round differently in its last bit.
    """
    params = list(params)
    rate: float | torch.Tensor = lr
    first: dict[str, Any] = {"fused": True}
    fallback: dict[str, Any] = {}
    if device is not None:
        dtype = torch.float32 if device.type == "cuda" else torch.float64
        rate = torch.tensor(lr, dtype=dtype, device=device)
        capturable = {"capturable": True} if device.type == "cuda" else {}
        first = {"fused": True, **capturable}
        # Without the fused kernel a tensor rate needs the single-tensor one (or capturable).
        fallback = {"foreach": False, **capturable}
    try:
        return torch.optim.Adam(params, lr=rate, **first)
    except (RuntimeError, TypeError):  # older torch / unsupported device
        return torch.optim.Adam(params, lr=rate, **fallback)


def _numpy_state(net: nn.Module) -> dict[str, np.ndarray]:
    return {k: v.detach().cpu().numpy().copy() for k, v in net.state_dict().items()}


class D4PGLearner:
    """Single-learner D4PG (Barth-Maron et al. 2018) with Ape-X style prioritized replay."""

    def __init__(self, config: D4PGConfig, obs_dim: int, act_dim: int, seed: int = 0) -> None:
        self.config, self.obs_dim, self.act_dim = config, obs_dim, act_dim
        if config.num_threads > 0:
            torch.set_num_threads(config.num_threads)
        torch.manual_seed(seed)
        self.device = pick_device(config.device)
        if self.device.type == "cpu":
            # Saturated tanh/softmax gradients become denormal floats, which x86 CPUs process
            # ~100x slower; measured here a learner step went from ~9 ms to >100 ms at times.
            # Flushing them to zero changes nothing that matters for training.
            torch.set_flush_denormal(True)
        c = config
        self.policy = Policy(obs_dim, act_dim, c.policy_hidden, c.layer_norm).to(self.device)
        features = critic_features(c.critic_features, obs_dim, act_dim)
        self.critic = DistributionalCritic(
            obs_dim, act_dim, c.critic_hidden, c.num_atoms, c.layer_norm, features
        ).to(self.device)
        for net in (self.policy, self.critic):
            net.set_action_box(c.action_box_low, c.action_box_high)
        self.target_policy = copy.deepcopy(self.policy).requires_grad_(False)
        self.target_critic = copy.deepcopy(self.critic).requires_grad_(False)
        self.policy_average: Policy | None = (
            copy.deepcopy(self.policy).requires_grad_(False) if c.policy_average_tau > 0 else None
        )
        whole_step = c.whole_step == "on" or (
            c.whole_step == "auto" and self.device.type == "cuda" and not c.compile
        )
        lr_device = self.device if whole_step else None
        self.policy_opt = make_adam(self.policy.parameters(), c.policy_lr, lr_device)
        self.critic_opt = make_adam(self.critic.parameters(), c.critic_lr, lr_device)
        self.support = make_support(c.v_min, c.v_max, c.num_atoms, self.device)
        alpha = c.priority_exponent if c.prioritized else 0.0  # alpha 0 == uniform sampling
        on_device = (
            whole_step
            or c.replay_device == "learner"
            or (c.replay_device == "auto" and self.device.type != "cpu")
        )
        self.replay = PrioritizedReplay(
            c.replay_capacity, obs_dim, act_dim, alpha, c.priority_eps, seed=seed,
            backend=Backend.torch_on(self.device) if on_device else None,
        )  # fmt: skip
        self.num_steps = 0
        self.device_loop: WholeStep | None = WholeStep(self) if whole_step else None
        """The device-stepped loop (``whole_step``: no host value read), or None: the
        host-stepped loop of :meth:`run`."""
        self._critic_loss_fn, self._policy_loss_fn = self._critic_loss, self._policy_loss
        if c.compile:
            # The losses (forward and backward) are compiled; the fused optimizer steps and the
            # replay stay as they are. "reduce-overhead" adds CUDA graphs on a GPU.
            self._critic_loss_fn = torch.compile(self._critic_loss, mode=c.compile)
            self._policy_loss_fn = torch.compile(self._policy_loss, mode=c.compile)

    # --- data in ------------------------------------------------------------------------
    def add(self, batch: dict[str, np.ndarray], priorities: np.ndarray | None = None) -> None:
        """Insert n-step transitions; ``priorities=None`` uses the replay's running max."""
        self.replay.add(batch, priorities)

    def can_step(self) -> bool:
        return len(self.replay) >= max(self.config.min_replay_size, self.config.batch_size)

    def set_lr(self, step: Any) -> Any:
        """Both optimizers' rates for learner step ``step``; returns the scale.

        Set on every step, decay or not: a restored optimizer state carries the rate it was
        saved with, which must not override this config's (another schedule, or none). A tensor
        rate (the whole step's) is written in place, from a device value when ``step`` is one.
        """
        scale = lr_scale(self.config, step)
        for opt, base in (
            (self.policy_opt, self.config.policy_lr),
            (self.critic_opt, self.config.critic_lr),
        ):
            for group in opt.param_groups:
                rate = base * scale
                if not isinstance(group["lr"], torch.Tensor):
                    group["lr"] = rate
                elif isinstance(rate, torch.Tensor):
                    group["lr"].copy_(rate)
                else:
                    group["lr"].fill_(rate)
        return scale

    # --- learning -----------------------------------------------------------------------
    def _to_tensors(self, batch: dict[str, np.ndarray]) -> dict[str, torch.Tensor]:
        return {k: torch.as_tensor(v, device=self.device) for k, v in batch.items()}

    def _target_distribution(self, b: dict[str, torch.Tensor]) -> torch.Tensor:
        with torch.no_grad():
            next_obs = b["next_obs"]
            next_logits = self.target_critic(next_obs, self.target_policy(next_obs)).float()
            return categorical_projection(
                torch.softmax(next_logits, -1), b["reward"], b["discount"], self.support
            )

    def step(self) -> dict[str, float]:
        """One learner step (``run(1)``)."""
        return self.run(1)

    def run(self, steps: int) -> dict[str, float]:
        """``steps`` learner steps: sample, critic + policy update, priorities, targets.

        Blocks of ``sgd_steps_per_sample`` batches are sampled at once (strided, so each batch
        spans every priority stratum); with 1 (the default) each step samples after the
        previous one's priorities, as always. Metrics stay on the device until the end of the
        call and come to the host in one copy.

        Returns:
            Metrics averaged over the steps: critic_loss, policy_loss, mean_q, mean_priority,
            beta, lr_scale, grad norms; and steps (the learner's total).
        """
        c = self.config
        if steps <= 0:
            return {}
        if self.device_loop is not None:
            return self._metrics(*self.device_loop.run(steps), steps)
        sums, beta_sum, lr_sum, done = None, 0.0, 0.0, 0
        while done < steps:
            k = min(c.sgd_steps_per_sample, steps - done)
            beta = importance_beta(c, self.num_steps)
            batch, idx, weights = self.replay.sample(k * c.batch_size, beta)
            block = self._to_tensors(batch)
            w = torch.as_tensor(weights, device=self.device)
            for j in range(k):
                part = slice(j, None, k)
                lr_sum += self.set_lr(self.num_steps)
                b = {key: v[part] for key, v in block.items()}
                stats, per_sample = self.gradient_step(b, w[part])
                if c.prioritized:
                    # A host replay takes NumPy (a CPU learner copies nothing); a device
                    # replay keeps the priorities where they were computed.
                    on_host = self.replay.backend.on_host
                    self.replay.update_priorities(
                        idx[part], per_sample.cpu().numpy() if on_host else per_sample
                    )
                self.num_steps += 1
                self.update_targets()
                sums = stats if sums is None else sums + stats
                beta_sum += beta
            done += k
        return self._metrics((sums / steps).cpu().numpy(), beta_sum, lr_sum, steps)

    def _metrics(
        self, mean: np.ndarray, beta_sum: float, lr_sum: float, steps: int
    ) -> dict[str, float]:
        """``run``'s metrics from the means of :attr:`STATS` and the schedules' sums."""
        means = {name: float(x) for name, x in zip(self.STATS, mean, strict=True)}
        return {
            **means,
            "beta": beta_sum / steps,
            "lr_scale": lr_sum / steps,
            "steps": float(self.num_steps),
        }

    def _critic_loss(
        self, b: dict[str, torch.Tensor], w: torch.Tensor
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """The importance-weighted cross-entropy to the projected target, and per sample."""
        with self._autocast():
            target = self._target_distribution(b)
            logits = self.critic(b["obs"], b["action"]).float()
        per_sample = categorical_cross_entropy(logits, target)
        return (w * per_sample).mean(), per_sample.detach()

    def _policy_loss(
        self, b: dict[str, torch.Tensor]
    ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """DPG: minus the critic's mean of the policy's action; with ``policy_smoothness``,
        plus that weight times the policy's squared change across each n-step window.

        Returns:
            The loss, the critic's mean of the policy's action, and the mean squared change
            (0 when the weight is 0: the second policy pass is then skipped).
        """
        with self._autocast():
            action = self.policy(b["obs"])
            logits = self.critic(b["obs"], action).float()
            mean_q = expected_value(logits, self.support).mean()
            change = torch.zeros((), device=mean_q.device)
            if self.config.policy_smoothness > 0:
                # A window that an episode's end cut short (discount 0) has no later state of
                # the same episode to compare with.
                alive = (b["discount"] > 0).float()
                moved = (action - self.policy(b["next_obs"])).float().square().sum(-1)
                change = (alive * moved).sum() / alive.sum().clamp(min=1.0)
        return -mean_q + self.config.policy_smoothness * change, mean_q, change

    STATS = (
        "critic_loss",
        "policy_loss",
        "critic_grad_norm",
        "policy_grad_norm",
        "mean_priority",
        "mean_q",
        "policy_change",
    )
    """The per-step statistics :meth:`gradient_step` stacks, in its order."""

    def gradient_step(
        self, b: dict[str, torch.Tensor], w: torch.Tensor
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """One gradient step of each network on batch ``b`` with importance weights ``w``.

        Returns:
            The :attr:`STATS` on the device, and the per-sample critic losses (new priorities).
        """
        critic_loss, per_sample = self._critic_loss_fn(b, w)
        # Outputs of a CUDA-graph replay are overwritten by the next replay: what outlives this
        # step is copied out now (a no-op for the values on every other path).
        critic_value, per_sample = critic_loss.detach().clone(), per_sample.clone()
        self.critic_opt.zero_grad(set_to_none=True)
        critic_loss.backward()
        critic_norm = self._clip(self.critic)
        self.critic_opt.step()

        # Only policy gradients are requested, so autograd skips the critic's weight gradients
        # (about a third of the backward work).
        policy_loss, mean_q, change = self._policy_loss_fn(b)
        params = list(self.policy.parameters())
        for p, g in zip(params, torch.autograd.grad(policy_loss, params), strict=True):
            p.grad = g
        policy_norm = self._clip(self.policy)
        self.policy_opt.step()
        losses = (critic_value, policy_loss.detach(), critic_norm, policy_norm)
        rest = (per_sample.mean(), mean_q.detach(), change.detach())
        stats = torch.stack([x.float() for x in (*losses, *rest)])
        return stats, per_sample

    def _autocast(self) -> contextlib.AbstractContextManager:
        """bf16 autocast around the networks when ``bf16`` is set (losses stay float32)."""
        if not self.config.bf16:
            return contextlib.nullcontext()
        # Autocast's cache of cast weights must not outlive a CUDA graph's capture.
        cache = self.device_loop is None
        return torch.autocast(self.device.type, dtype=torch.bfloat16, cache_enabled=cache)

    def _clip(self, net: nn.Module) -> torch.Tensor:
        if self.config.max_grad_norm > 0:
            return nn.utils.clip_grad_norm_(
                net.parameters(), self.config.max_grad_norm, foreach=True
            )
        return torch.zeros((), device=self.device)

    def update_targets(self, due: torch.Tensor | None = None) -> None:
        """Polyak or hard target updates after a step. ``due``: whether a hard copy is due, as
        a device bool (the whole step's; the copy becomes a ``where``), else decided here."""
        c = self.config
        pairs = ((self.policy, self.target_policy), (self.critic, self.target_critic))
        with torch.no_grad():
            for online, target in pairs:
                src, dst = list(online.parameters()), list(target.parameters())
                if c.target_tau > 0:
                    torch._foreach_lerp_(dst, src, c.target_tau)
                elif due is not None:
                    for d, s in zip(dst, src, strict=True):
                        d.copy_(torch.where(due, s, d))
                elif self.num_steps % c.target_update_period == 0:
                    torch._foreach_copy_(dst, src)
            if self.policy_average is not None:
                torch._foreach_lerp_(
                    list(self.policy_average.parameters()),
                    list(self.policy.parameters()),
                    c.policy_average_tau,
                )

    # --- priorities for actors ----------------------------------------------------------
    def compute_initial_priorities(self, batch: dict[str, np.ndarray]) -> np.ndarray:
        """Priorities for new transitions with the current networks (no gradients).

        Same quantity the learner writes back (the unweighted critic cross-entropy), so new
        data competes on equal terms. Ape-X computes this on the actors; ours hold only the
        policy, so either the learner calls this on arriving batches or actors insert with
        ``priorities=None`` (running max).
        """
        b = self._to_tensors(batch)
        with torch.no_grad():
            target = self._target_distribution(b)
            ce = categorical_cross_entropy(self.critic(b["obs"], b["action"]), target)
        return ce.cpu().numpy()

    # --- weights & checkpoints ----------------------------------------------------------
    def get_weights(self) -> dict[str, np.ndarray]:
        """Online policy weights as CPU numpy arrays (cheap to put in Ray's object store)."""
        return _numpy_state(self.policy)

    def get_eval_weights(self) -> dict[str, np.ndarray]:
        """The policy to evaluate and ship: the Polyak average when kept, else the online one."""
        return _numpy_state(self.policy if self.policy_average is None else self.policy_average)

    def set_weights(self, weights: dict[str, np.ndarray]) -> None:
        self.policy.load_state_dict({k: torch.as_tensor(v) for k, v in weights.items()})

    def save(self, path: str | os.PathLike, include_replay: bool = False) -> None:
        """Write networks, targets, optimizers, counters to ``path`` and, with
        ``include_replay``, the replay beside it (layout: ``learner/checkpoint.py``)."""
        checkpoint.write_atomic(path, checkpoint.learner_state(self))
        if include_replay:
            checkpoint.write_replay(checkpoint.replay_path(path), self.replay.state_dict())

    def restore(self, path: str | os.PathLike) -> None:
        """Load what :meth:`save` wrote; the replay too when its file exists.

        A checkpoint without a policy average (averaging was off) starts the average at the
        restored online policy; one with an average restored by a learner that keeps none
        drops it.
        """
        state = checkpoint.read(path, self.device)
        nets = state["nets"]
        for name, sd in nets.items():
            if getattr(self, name) is not None:
                getattr(self, name).load_state_dict(sd)
        if self.policy_average is not None and "policy_average" not in nets:
            self.policy_average.load_state_dict(self.policy.state_dict())
        for opt, saved in ((self.policy_opt, "policy"), (self.critic_opt, "critic")):
            rates = [group["lr"] for group in opt.param_groups]
            opt.load_state_dict(state["opts"][saved])
            for group, rate in zip(opt.param_groups, rates, strict=True):
                if isinstance(rate, torch.Tensor):  # keep the whole step's tensor rate
                    group["lr"] = rate
        self.num_steps = int(state["num_steps"])
        torch.set_rng_state(state["torch_rng"].cpu())
        if "cuda_rng" in state and self.device.type == "cuda":
            torch.cuda.set_rng_state(state["cuda_rng"].cpu())
        if checkpoint.replay_path(path).exists():
            self.replay.load_state_dict(checkpoint.read_replay(checkpoint.replay_path(path)))
        if self.device_loop is not None:
            self.device_loop.forget()
