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


@pytest.mark.parametrize(("max_wall_s", "shown"), [(120, r"\[00:30<01:(29|30),"),
                                                   (None, r"\[00:30<4:59:[23]\d,")])  # fmt: skip
def test_the_bar_shows_the_earlier_time_left(max_wall_s: float | None, shown: str) -> None:
    bar = ProgressBar(total=60_000, file=io.StringIO(), max_wall_s=max_wall_s, smoothing=0)
    bar.update(100)
    bar.start_t -= 30  # 100 steps in 30 s: the step total is hours away
    assert re.search(shown, str(bar)), str(bar)
    bar.close()
