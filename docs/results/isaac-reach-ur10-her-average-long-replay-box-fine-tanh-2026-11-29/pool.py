"""Per-seed and pooled medians of the final position errors in ``evaluate``'s
evaluation.json files, with bootstrap 95 % intervals (5,000 resamples, generator seed 0).

    python pool.py seed0/evaluation.json seed1/evaluation.json seed2/evaluation.json
"""

import json
import sys
from pathlib import Path

import numpy as np

rng = np.random.default_rng(0)


def interval(errors: np.ndarray) -> np.ndarray:
    medians = [np.median(rng.choice(errors, len(errors))) for _ in range(5000)]
    return np.percentile(medians, [2.5, 97.5])


pooled = []
for path in sys.argv[1:]:
    episodes = json.loads(Path(path).read_text())["episodes"]
    errors = np.array([e["position_error"] for e in episodes])
    pooled.append(errors)
    success = np.mean([e["final_status"] == "success" for e in episodes])
    low, high = interval(errors)
    print(f"{path}: success {success:.2f}, median {np.median(errors) * 100:.3f} cm "
          f"({low * 100:.3f}-{high * 100:.3f})")  # fmt: skip
errors = np.concatenate(pooled)
low, high = interval(errors)
size, median = len(errors), np.median(errors) * 100
print(f"pooled ({size}): median {median:.3f} cm ({low * 100:.3f}-{high * 100:.3f})")
