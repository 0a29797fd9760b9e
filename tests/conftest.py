"""Suite-wide settings: Ray's CLI and the embedded Ray must agree on authentication."""

from __future__ import annotations

import os

# Ray 2.60 enables token auth by default; `ray start` / `ray job submit` in the tests and the
# embedded `ray.init` must see the same mode, so the whole suite runs with it disabled.
os.environ.setdefault("RAY_AUTH_MODE", "disabled")
# Keep Ray's usage-stats prompt and dashboard out of test runs (no network here anyway).
os.environ.setdefault("RAY_USAGE_STATS_ENABLED", "0")
