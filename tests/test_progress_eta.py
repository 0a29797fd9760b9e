"""The progress bar's time left is the earlier of the step total's and ``--max-wall-s``'s
(until 2026-11-27 a run about to stop at its wall limit showed 47 minutes left)."""

from __future__ import annotations

import io
import re

import pytest

from robogym_ray.training.logger import ProgressBar, eta_s


def test_eta_is_the_earlier_of_the_step_total_and_the_wall_limit() -> None:
    assert eta_s(1000, 1_000_000, 60.0, 10.0) == pytest.approx(99_900)
    assert eta_s(1000, 1_000_000, 60.0, 10.0, max_wall_s=90) == pytest.approx(30)
    assert eta_s(999_000, 1_000_000, 60.0, 10.0, max_wall_s=900) == pytest.approx(100)
    assert eta_s(0, 1000, 5.0, None, max_wall_s=60) == pytest.approx(55)  # no rate yet
    assert eta_s(0, 1000, 5.0, None) is None
    assert eta_s(10, 1000, 70.0, 1.0, max_wall_s=60) == 0.0  # past it: stopping now
    assert eta_s(3016, 3000, 18.0, 167.0) == 0.0  # steps in flight landed past the total
    assert eta_s(3016, None, 18.0, 167.0) is None  # no step cap and no wall limit
    assert eta_s(3016, None, 18.0, 167.0, max_wall_s=150) == pytest.approx(132)


@pytest.mark.parametrize(("max_wall_s", "shown"), [(120, r"\[00:30<01:(29|30),"),
                                                   (None, r"\[00:30<4:59:[23]\d,")])  # fmt: skip
def test_the_bar_shows_the_earlier_time_left(max_wall_s: float | None, shown: str) -> None:
    bar = ProgressBar(total=60_000, file=io.StringIO(), max_wall_s=max_wall_s, smoothing=0)
    bar.update(100)
    bar.start_t -= 30  # 100 steps in 30 s: the step total is hours away
    assert re.search(shown, str(bar)), str(bar)
    bar.close()


@pytest.mark.parametrize(("total", "max_wall_s", "shown"), [
    (3000, None, r"100%\|#+\| 3016/3000 \[00:18<00:00,"),  # past the total: full, no "-00:00"
    (None, 150, r" 3016/\? \[00:18<02:1[12],"),  # no step cap: the wall limit's time left
    (None, None, r" 3016/\? \[00:18<\?,"),
])  # fmt: skip
def test_the_bar_never_shows_a_negative_time_left(
    total: int | None, max_wall_s: float | None, shown: str
) -> None:
    bar = ProgressBar(total=total, file=io.StringIO(), max_wall_s=max_wall_s, smoothing=0)
    bar.update(3016)
    bar.start_t -= 18
    assert re.search(shown, str(bar)), str(bar)
    assert "<-" not in str(bar)
    bar.close()
