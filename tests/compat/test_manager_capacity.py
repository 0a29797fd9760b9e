"""A default ``robogym-ray manager`` (local Ray, 2 CPUs) under robo-gym's own server-manager client
asking for 24 robot servers and killing none.

Before 2026-11-23: each server reserved 0.25 Ray CPU, so the 8th start blocked ~60 s and failed,
robo-gym's client retried it 10 times, and concurrent starts took every gRPC thread so
VerifyConnection stopped answering. Now: every call is answered within 15 s and at least 16
servers are served.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.compat.conftest import _env, free_port
from tests.compat.harness import run_robo_gym, start_cli, stop

pytestmark = pytest.mark.slow

SERVERS = 24
CLIENTS = 4  # environments built side by side, each with its own robo-gym client
ANSWER_WITHIN_S = 15.0


def test_default_manager_serves_24_robo_gym_clients_without_kills(
    robo_gym_python: Path, compat_tmp: Path
) -> None:
    ray_tmp = compat_tmp / "ray-capacity"
    ray_tmp.mkdir()
    port = free_port()
    manager = start_cli(
        ["manager", "--port", str(port)],  # every other setting at its default (2 CPUs ...)
        compat_tmp / "manager-capacity.log",
        timeout=120,
        env=_env(RAY_TMPDIR=str(ray_tmp), RAY_ADDRESS=""),
    )
    try:
        out = run_robo_gym(
            robo_gym_python,
            "manager_capacity.py",
            "127.0.0.1",
            str(port),
            str(SERVERS),
            str(CLIENTS),
            timeout=900,
        )
    finally:
        stop(manager.proc)
    served = [env for env in out["envs"] if env["address"]]
    slowest = max(call["s"] for call in out["calls"])
    print(
        f"\n{len(served)}/{SERVERS} served in {out['total_s']:.0f} s; "
        f"{len(out['calls'])} StartNewServer calls, slowest {slowest:.1f} s; "
        f"VerifyConnection slowest {max(v['s'] for v in out['verify']):.2f} s; call times (s, "
        f"ok): {sorted((round(c['s'], 1), c['ok']) for c in out['calls'])}"
    )
    assert len(served) >= 16, out["envs"]
    assert len({env["address"] for env in served}) == len(served)
    assert slowest < ANSWER_WITHIN_S
    assert out["verify"] and all(v["ok"] and v["s"] < ANSWER_WITHIN_S for v in out["verify"])
