"""A trial's placement-group bundles, made from the rows of the run's actor table
(``training/resources.py``), and the check that a trial's actors fit the bundles it got (no
Ray here)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence

from robogym_ray.errors import ConfigError
from robogym_ray.training.resources import ActorNeed, describe


def bundles(needs: Sequence[ActorNeed], own: Mapping[str, float]) -> list[dict[str, float]]:
    """A trial's placement-group bundles: ``own`` (the trial's driver, bundle 0) and one per
    actor. One each, because Ray checks that an actor fits some bundle, not that the bundles
    add up to every actor: a shared bundle would leave actors waiting, not refused."""
    out = [dict(own)]
    for need in needs:
        out += [need.bundle() for _ in range(need.count)]
    return out


def check_fit(needs: Sequence[ActorNeed], available: Sequence[Mapping[str, float]]) -> None:
    """Refuse, in one line, actors that the bundles ``available`` (a trial's, less its own)
    cannot all hold: each actor must fit one bundle's room left by the actors placed before it
    (largest first). Ray itself would only refuse an actor bigger than every bundle and leave
    the rest waiting forever."""
    room = [dict(b) for b in available]
    for need in sorted(needs, key=lambda n: (-n.gpus, -n.cpus)):
        for _ in range(need.count):
            want = need.bundle()
            slot = next((r for r in room if _holds(r, want)), None)
            if slot is None:
                raise ConfigError(
                    f"the trial's actors need {describe(needs)} but its placement group holds "
                    f"{_sum(available)} besides the trial's own bundle (no room for the "
                    f"{need.role}: {want}); build its resources with "
                    "robogym_ray.sweep.trial.trial_resources(config)"
                )
            for k, v in want.items():
                slot[k] -= v


def _holds(room: Mapping[str, float], want: Mapping[str, float]) -> bool:
    return all(room.get(k, 0.0) + 1e-9 >= v for k, v in want.items())


def _sum(available: Sequence[Mapping[str, float]]) -> str:
    total: dict[str, float] = {}
    for b in available:
        for k, v in b.items():
            total[k] = total.get(k, 0.0) + v
    return ", ".join(f"{v:g} {k}" for k, v in sorted(total.items())) or "nothing"
