"""The learner's default path before and after ``policy_smoothness``: 200 steps of a learner
with the fine-tanh config's settings (weight 0) on fixed random transitions, run from the
checkout given, and a digest of its policy, critic and policy average afterwards. Equal digests
from two checkouts mean the term's default leaves every step bit for bit as it was.

    git worktree add /tmp/old-src 3412504
    python docs/results/isaac-reach-ur10-smooth-2026-12-01/same_steps.py /tmp/old-src
    python docs/results/isaac-reach-ur10-smooth-2026-12-01/same_steps.py .
"""

import hashlib
import sys

import numpy as np

sys.path.insert(0, sys.argv[1])  # the checkout under test, ahead of the installed one

from robogym_ray.learner.config import D4PGConfig  # noqa: E402
from robogym_ray.learner.learner import D4PGLearner  # noqa: E402

OBS, ACT, N = 25, 6, 2000


def main() -> None:
    rng = np.random.default_rng(0)
    data = {
        "obs": rng.standard_normal((N, OBS), dtype=np.float32),
        "action": rng.uniform(-1, 1, (N, ACT)).astype(np.float32),
        "reward": rng.uniform(-1, 1, N).astype(np.float32),
        "discount": rng.choice([0.0, 0.99**5], N).astype(np.float32),
        "next_obs": rng.standard_normal((N, OBS), dtype=np.float32),
    }
    config = D4PGConfig(
        layer_norm=True, v_min=-4.0, v_max=2.0, policy_lr=3e-4, critic_lr=3e-4,
        policy_average_tau=2e-4, action_box_low=(-0.25, -0.5, 0.0, -0.5, -0.5, -0.5),
        action_box_high=(0.25, 0.0, 1.0, 0.5, 0.5, 0.5), device="cpu", num_threads=1,
    )  # fmt: skip
    learner = D4PGLearner(config, OBS, ACT, seed=0)
    learner.add(data)
    metrics = learner.run(200)
    digest = hashlib.sha256()
    for net in (learner.policy, learner.critic, learner.policy_average):
        for p in net.parameters():
            digest.update(p.detach().numpy().tobytes())
    print(learner.num_steps, digest.hexdigest()[:16], f"mean_q {metrics['mean_q']:.6f}")


if __name__ == "__main__":
    main()
