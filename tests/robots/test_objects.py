"""Object trajectories of spec c.2.4, sampled at 100 Hz."""

from __future__ import annotations

import numpy as np
import pytest

from robogym_ray.errors import InvalidStateError
from robogym_ray.robots.objects import build_trajectory


def _build(function: str, seed: int = 0, **params: float):
    floats = {f"object_0_{k}": v for k, v in params.items()}
    return build_trajectory(0, {"object_0_function": function}, floats, np.random.default_rng(seed))


def test_fixed_position_is_constant():
    traj = _build("fixed_position", x=0.3, y=-0.2, z=0.5)
    for t in (0.0, 0.013, 7.5, 1000.0):
        np.testing.assert_allclose(traj.position(t), (0.3, -0.2, 0.5))


def test_triangle_wave_at_known_times():
    traj = _build("triangle_wave", x=0.12, y=0.34, z_amplitude=0.2, z_frequency=0.125, z_offset=0.4)
    assert len(traj.samples) == 800  # int(100 / f) samples per period
    expected = {0.0: 0.2, 2.0: 0.4, 4.0: 0.6, 6.0: 0.4, 8.0: 0.2, 10.0: 0.4, 1.0: 0.3}
    for t, z in expected.items():
        np.testing.assert_allclose(traj.position(t), (0.12, 0.34, z), atol=1e-9)
    # One sample per 10 ms: values are held between samples.
    np.testing.assert_allclose(traj.position(2.0049), traj.position(2.0))


def test_fixed_position_ab_holds_then_switches_and_loops():
    traj = _build(
        "fixed_position_ab", x_a=1, y_a=2, z_a=3, x_b=4, y_b=5, z_b=6, hold_a=1.0, hold_b=0.5
    )
    np.testing.assert_allclose(traj.position(0.99), (1, 2, 3))
    np.testing.assert_allclose(traj.position(1.0), (4, 5, 6))
    np.testing.assert_allclose(traj.position(1.49), (4, 5, 6))
    np.testing.assert_allclose(traj.position(1.5), (1, 2, 3))


def test_interpolated_abc_passes_through_a_b_c():
    params = dict(
        x_a=0,
        y_a=0,
        z_a=0,
        x_b=1,
        y_b=0,
        z_b=0,
        x_c=1,
        y_c=1,
        z_c=0,
        hold_a=0.1,
        hold_b=0.1,
        hold_c=0.1,
        n_sampling_points_ab=11,
        n_sampling_points_bc=11,
    )
    traj = _build("interpolated_abc", **params)
    assert len(traj.samples) == 10 + 11 + 10 + 11 + 10
    np.testing.assert_allclose(traj.position(0.0), (0, 0, 0))
    np.testing.assert_allclose(traj.position(0.15), (0.5, 0, 0))  # middle of a -> b
    np.testing.assert_allclose(traj.position(0.25), (1, 0, 0))  # holding b
    np.testing.assert_allclose(traj.position(0.515), (1, 1, 0))  # holding c


SPLINE = dict(
    x_min=-1.0,
    x_max=1.0,
    y_min=-1.0,
    y_max=1.0,
    z_min=0.1,
    z_max=1.0,
    n_points=10,
    n_sampling_points=9000,
)


def test_3d_spline_stays_near_the_box_is_closed_and_seeded():
    traj = _build("3d_spline", seed=3, **SPLINE)
    assert traj.samples.shape == (9000, 3)
    np.testing.assert_allclose(traj.samples[0], traj.samples[-1], atol=1e-9)
    np.testing.assert_allclose(traj.position(90.0), traj.samples[0])  # one lap = 90 s
    np.testing.assert_array_equal(traj.samples, _build("3d_spline", seed=3, **SPLINE).samples)
    assert not np.array_equal(traj.samples, _build("3d_spline", seed=4, **SPLINE).samples)


def test_3d_spline_ur5_workspace_keeps_clear_of_the_robot():
    traj = _build("3d_spline_ur5_workspace", seed=1, **SPLINE)
    s = traj.samples
    assert np.hypot(s[:, 0], s[:, 1]).min() > 0.2
    assert np.linalg.norm(s, axis=1).min() > 0.35
    assert 0.5 <= abs(s[0, 0]) <= 1.0 and 0.5 <= abs(s[0, 1]) <= 1.0


def test_missing_function_means_keep_previous():
    assert build_trajectory(0, {}, {}, np.random.default_rng(0)) is None


@pytest.mark.parametrize(
    ("function", "params", "match"),
    [
        ("wobble", {}, "unknown object_0_function 'wobble'"),
        ("fixed_trajectory", {"trajectory_id": 50.0}, r"object_0_trajectory_id = 50.0"),
        ("fixed_trajectory", {"trajectory_id": 1.5}, "not an integer"),
        ("fixed_position", {"x": 0.1, "y": 0.2}, "object_0_z"),
        ("fixed_position", {"x": 0.1, "y": 0.2, "z": float("nan")}, "non-finite"),
        ("triangle_wave", dict(x=0, y=0, z_amplitude=1, z_frequency=0, z_offset=0), "z_frequency"),
        ("3d_spline", {**SPLINE, "n_points": 2}, "n_points >= 4"),
        (
            "fixed_position_ab",
            dict(x_a=0, y_a=0, z_a=0, x_b=0, y_b=0, z_b=0, hold_a=0, hold_b=0),
            "no samples",
        ),
        (
            "3d_spline_ur5_workspace",
            {
                **SPLINE,
                "x_min": -0.01,
                "x_max": 0.01,
                "y_min": -0.01,
                "y_max": 0.01,
                "n_sampling_points": 50,
            },
            "draws",
        ),
    ],
)
def test_bad_parameters_raise_invalid_state(function, params, match):
    with pytest.raises(InvalidStateError, match=match):
        _build(function, **params)
