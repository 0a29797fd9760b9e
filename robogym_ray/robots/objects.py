"""Object trajectories of robo-gym's objects controller (spec c.2.4), sampled at 100 Hz.

Robot-generic: any arm's server that moves objects on SetState (``rs_mode`` with objects) builds
them here; the function names are robo-gym's wire names (``3d_spline_ur5_workspace`` included).

A SetState carries ``object_<i>_function`` in ``string_params`` and the function's parameters as
``object_<i>_<name>`` floats. Each function becomes a looping array of xyz samples (reference
frame), one per 10 ms of *sim* time; ``ObjectTrajectory.position(t)`` picks the sample in force at
``t`` seconds after the start, exactly as the ROS controller publishes one sample per 10 ms.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass

import numpy as np
from scipy.interpolate import splev, splprep
from scipy.signal import sawtooth

from robogym_ray.errors import InvalidStateError
from robogym_ray.robots.validation import check_range
from robogym_ray.text import quote

SAMPLE_RATE = 100.0
"""Samples per second of every trajectory."""
MAX_LAP_S = 300.0
"""Longest stretch of one trajectory (a triangle period, a hold, a spline lap) in seconds. Whole
laps are precomputed, so this bounds the samples of one piece to 30,000 (720 kB; a
``z_frequency`` of 1e-5 Hz would need 1e7 samples). robo-gym's envs use 8 s periods and 80-120 s
spline laps."""
MAX_SAMPLES = int(MAX_LAP_S * SAMPLE_RATE)
MAX_ABS_COORDINATE = 10.0
"""Bound on every object coordinate, box corner, offset and amplitude (m, reference frame). The
longest UR reaches 1.3 m and parked objects wait 3 m up; 3e38 m is a client bug, not a pose."""
MAX_SPLINE_POINTS = 1000
"""Control points of one spline (robo-gym: 10); each redraw of the UR5-workspace spline fits them
all again."""
PARK_Z = 3.0
"""Parked objects wait at (i, 0, 3) m in the reference frame (ROS: while the arm moves)."""
MAX_SPLINE_TRIES = 1000
"""Redraws before 3d_spline_ur5_workspace gives up (an impossible box would loop forever)."""


@dataclass(frozen=True)
class ObjectTrajectory:
    """A looping sequence of positions, one per 1/SAMPLE_RATE s."""

    function: str
    samples: np.ndarray
    """(N, 3) xyz in the reference frame, N >= 1."""

    def index(self, t: float) -> int:
        """Sample index in force ``t`` s after the start (small epsilon against float drift)."""
        return int(math.floor(max(t, 0.0) * SAMPLE_RATE + 1e-6)) % len(self.samples)

    def position(self, t: float) -> np.ndarray:
        return self.samples[self.index(t)]


def parked(index: int) -> ObjectTrajectory:
    return ObjectTrajectory("parked", np.array([[float(index), 0.0, PARK_Z]]))


# -- the functions ----------------------------------------------------------------------------
Params = Mapping[str, float]
Builder = Callable[[Params, np.random.Generator], np.ndarray]


def _fixed_position(p: Params, rng: np.random.Generator) -> np.ndarray:
    return np.array([[p["x"], p["y"], p["z"]]])


def _triangle_wave(p: Params, rng: np.random.Generator) -> np.ndarray:
    freq = p["z_frequency"]  # within PARAM_RANGES: one period is <= MAX_SAMPLES samples
    n = max(1, int(SAMPLE_RATE / freq))
    t = np.arange(n) / SAMPLE_RATE
    # width 0.5 makes sawtooth a symmetric triangle wave in [-1, 1] starting at -1.
    z = p["z_offset"] + p["z_amplitude"] * sawtooth(2 * np.pi * freq * t, 0.5)
    return np.column_stack([np.full(n, p["x"]), np.full(n, p["y"]), z])


def _spline_samples(points: np.ndarray, n_samples: int) -> np.ndarray:
    # s=0: an interpolating spline through every control point; the closed loop comes from the
    # last control point repeating the first.
    tck, _ = splprep(points.T, s=0)
    return np.column_stack(splev(np.linspace(0.0, 1.0, n_samples), tck))


def _spline_counts(p: Params) -> tuple[int, int]:
    n_points, n_samples = int(p["n_points"]), int(p["n_sampling_points"])
    if n_points < 4 or n_samples < 1:
        raise InvalidStateError(
            f"3d spline needs n_points >= 4 and n_sampling_points >= 1, got "
            f"n_points={p['n_points']}, n_sampling_points={p['n_sampling_points']}"
        )
    return n_points, n_samples


def _box_points(p: Params, n: int, rng: np.random.Generator) -> np.ndarray:
    low = [p["x_min"], p["y_min"], p["z_min"]]
    high = [p["x_max"], p["y_max"], p["z_max"]]
    pts = rng.uniform(low, high, size=(n, 3))
    pts[-1] = pts[0]
    return pts


def _spline_3d(p: Params, rng: np.random.Generator) -> np.ndarray:
    n_points, n_samples = _spline_counts(p)
    return _spline_samples(_box_points(p, n_points, rng), n_samples)


def _spline_3d_ur5_workspace(p: Params, rng: np.random.Generator) -> np.ndarray:
    n_points, n_samples = _spline_counts(p)
    for _ in range(MAX_SPLINE_TRIES):
        pts = _box_points(p, n_points, rng)
        # The first point starts away from the robot, on one of the four sides.
        pts[0, :2] = rng.uniform(0.5, 1.0, size=2) * rng.choice([-1.0, 1.0], size=2)
        pts[-1] = pts[0]
        samples = _spline_samples(pts, n_samples)
        if (
            np.hypot(samples[:, 0], samples[:, 1]).min() > 0.2
            and np.linalg.norm(samples, axis=1).min() > 0.35
        ):
            return samples
    raise InvalidStateError(
        f"3d_spline_ur5_workspace: no curve in the box {dict(p)} stayed > 0.2 m from the z axis "
        f"and > 0.35 m from the origin in {MAX_SPLINE_TRIES} draws"
    )


FIXED_TRAJECTORIES = 50
"""Ids 0-49 of ``fixed_trajectory`` (robo-gym's AvoidanceRaad2022Test cycles through 50)."""
FIXED_TRAJECTORY_SEED = 2022
"""Root of every fixed trajectory's seed: trajectory ``k`` is drawn from
``SeedSequence([FIXED_TRAJECTORY_SEED, k])``, never from the server's RNG."""
FIXED_TRAJECTORY_BOX = {
    "x_min": -1.0, "x_max": 1.0, "y_min": -1.0, "y_max": 1.0, "z_min": 0.1, "z_max": 1.0,
    "n_points": 10.0,
}  # fmt: skip
"""The spline box AvoidanceRaad2022 sends with ``3d_spline_ur5_workspace`` (m, reference
frame); its lap of 8000-12000 samples is drawn per trajectory like the env draws it."""


def _fixed_trajectory(p: Params, rng: np.random.Generator) -> np.ndarray:
    # robo-gym reads 50 recorded splines from a JSON file of the ROS package; we draw ours the
    # way AvoidanceRaad2022 asks for random ones, from a generator seeded by the id alone, so
    # every server and every run serves the same trajectory for the same id (the server's
    # ``rng`` is not touched).
    trajectory_id = p["trajectory_id"]
    if trajectory_id != int(trajectory_id):
        raise InvalidStateError(
            f"fixed_trajectory: trajectory_id {trajectory_id!r} is not an integer id "
            f"(0-{FIXED_TRAJECTORIES - 1})"
        )
    own = np.random.Generator(
        np.random.PCG64(np.random.SeedSequence([FIXED_TRAJECTORY_SEED, int(trajectory_id)]))
    )
    n_samples = float(int(own.uniform(8000, 12000)))
    return _spline_3d_ur5_workspace({**FIXED_TRAJECTORY_BOX, "n_sampling_points": n_samples}, own)


def _hold(point: np.ndarray, seconds: float) -> np.ndarray:
    return np.repeat(point[None, :], max(0, int(seconds * SAMPLE_RATE)), axis=0)


def _line(a: np.ndarray, b: np.ndarray, n: float) -> np.ndarray:
    return np.linspace(a, b, max(0, int(n)))


def _point(p: Params, tag: str) -> np.ndarray:
    return np.array([p[f"x_{tag}"], p[f"y_{tag}"], p[f"z_{tag}"]])


def _fixed_position_ab(p: Params, rng: np.random.Generator) -> np.ndarray:
    a, b = _point(p, "a"), _point(p, "b")
    return np.concatenate([_hold(a, p["hold_a"]), _hold(b, p["hold_b"])])


def _interpolated_abc(p: Params, rng: np.random.Generator) -> np.ndarray:
    a, b, c = _point(p, "a"), _point(p, "b"), _point(p, "c")
    return np.concatenate(
        [
            _hold(a, p["hold_a"]),
            _line(a, b, p["n_sampling_points_ab"]),
            _hold(b, p["hold_b"]),
            _line(b, c, p["n_sampling_points_bc"]),
            _hold(c, p["hold_c"]),
        ]
    )


_SPLINE = ("x_min", "x_max", "y_min", "y_max", "z_min", "z_max", "n_points", "n_sampling_points")
_ABC = tuple(f"{k}_{t}" for t in "abc" for k in "xyz")
FUNCTIONS: dict[str, tuple[tuple[str, ...], Builder]] = {
    "fixed_position": (("x", "y", "z"), _fixed_position),
    "triangle_wave": (("x", "y", "z_amplitude", "z_frequency", "z_offset"), _triangle_wave),
    "3d_spline": (_SPLINE, _spline_3d),
    "3d_spline_ur5_workspace": (_SPLINE, _spline_3d_ur5_workspace),
    "fixed_trajectory": (("trajectory_id",), _fixed_trajectory),
    "fixed_position_ab": (_ABC[:6] + ("hold_a", "hold_b"), _fixed_position_ab),
    "interpolated_abc": (
        _ABC + ("hold_a", "hold_b", "hold_c", "n_sampling_points_ab", "n_sampling_points_bc"),
        _interpolated_abc,
    ),
}
"""function name -> (required float params without the ``object_<i>_`` prefix, builder)."""
_COORDINATE = (-MAX_ABS_COORDINATE, MAX_ABS_COORDINATE, "m")
_COUNT = (0.0, float(MAX_SAMPLES), "samples")
PARAM_RANGES: dict[str, tuple[float, float, str]] = {
    **{n: _COORDINATE for n in ("x", "y", "z", "z_amplitude", "z_offset", *_SPLINE[:6], *_ABC)},
    # One triangle period is SAMPLE_RATE / f samples: at most MAX_SAMPLES, and at least 2
    # (above the Nyquist frequency of the 100 Hz sampling the wave is not a triangle any more).
    "z_frequency": (SAMPLE_RATE / MAX_SAMPLES, SAMPLE_RATE / 2, "Hz"),
    "n_points": (0.0, float(MAX_SPLINE_POINTS), "points"),  # >= 4 is _spline_counts' check
    "n_sampling_points": _COUNT,
    "n_sampling_points_ab": _COUNT,
    "n_sampling_points_bc": _COUNT,
    **{f"hold_{t}": (0.0, MAX_LAP_S, "s") for t in "abc"},
    "trajectory_id": (0.0, float(FIXED_TRAJECTORIES - 1), "(an integer id)"),
}
"""Allowed range of each float parameter (low, high, unit), checked before anything is built."""


def build_trajectory(
    index: int,
    string_params: Mapping[str, str],
    float_params: Mapping[str, float],
    rng: np.random.Generator,
) -> ObjectTrajectory | None:
    """Object ``index``'s trajectory from SetState parameters.

    Returns:
        None when ``object_<index>_function`` is absent (the caller keeps the previous trajectory,
        like the ROS parameter server keeps the previous parameters).

    Raises:
        InvalidStateError: unknown function, missing parameters, parameters
            outside ``PARAM_RANGES`` (NaN/inf included), or parameters that give an empty
            trajectory.
    """
    prefix = f"object_{index}_"
    function = string_params.get(prefix + "function")
    if function is None:
        return None
    if function not in FUNCTIONS:
        raise InvalidStateError(
            f"unknown {prefix}function {quote(function)}; known: {', '.join(sorted(FUNCTIONS))}"
        )
    names, builder = FUNCTIONS[function]
    missing = [prefix + n for n in names if prefix + n not in float_params]
    if missing:
        raise InvalidStateError(f"{function} for object {index} needs float params {missing}")
    params = {n: check_range(prefix + n, float_params[prefix + n], *PARAM_RANGES[n]) for n in names}
    samples = np.asarray(builder(params, rng), dtype=np.float64)
    if samples.ndim != 2 or len(samples) == 0:
        raise InvalidStateError(f"{function} for object {index} gives no samples with {params}")
    return ObjectTrajectory(function, samples)
