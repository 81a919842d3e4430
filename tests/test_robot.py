"""The robot: its four spaces, load-aware inverse kinematics on the seed's three
trajectories with 0, 30 and 60 g, and what ignoring the load costs."""

from __future__ import annotations

import math

import numpy as np
import pytest

import softspine
from softspine import Robot, trajectories

LOADS = (0.0, 0.03, 0.06)


@pytest.fixture(scope="module")
def robot():
    return Robot()


def test_spaces_round_trip(robot):
    rng = np.random.default_rng(3)
    kappa = rng.uniform(-3, 3, size=(robot.sections, 2))
    lengths = robot.muscle_lengths(kappa)
    assert lengths.shape == (robot.sections, 3)
    assert np.allclose(robot.rest_curvature(lengths), kappa, atol=1e-12)
    times = robot.inflation_times(lengths)
    assert np.allclose(robot.muscle_lengths_from_times(times), lengths, atol=1e-15)
    # Curvature -> configuration -> task: the forward solve is the scene's solve.
    sol = robot.forward(kappa, load=0.03)
    direct = softspine.solve(robot.scene(kappa, load=0.03), n_elements=robot.n_elements)
    assert np.array_equal(sol.tip_position, direct.tip_position)


def test_muscle_geometry_matches_the_convention(robot):
    """kappa_y > 0 bends toward +x: the muscle nearest +x (330 deg) is the shortest."""
    lengths = robot.muscle_lengths([[0.0, 2.0]] + [[0.0, 0.0]] * (robot.sections - 1))[0]
    assert np.argmin(lengths) == 2
    # Length change l_s d (kx sin phi - ky cos phi), the common mode centred in range.
    lo, hi = robot.muscle_length_range
    phi = np.radians([90.0, 210.0, 330.0])
    delta = 0.1 * 0.02 * (-2.0 * np.cos(phi))
    assert np.allclose(lengths - lengths.mean(), delta - delta.mean(), atol=1e-15)
    assert lengths.max() + lengths.min() == pytest.approx(lo + hi)


def test_scene_has_weight_disks_and_tip_load(robot):
    scene = robot.scene(np.zeros((robot.sections, 2)), load=0.06)
    sol = softspine.solve(scene, n_elements=robot.n_elements)
    weight = (0.2 * 1.0 + 10 * 0.01 + 0.06) * 9.81
    assert np.allclose(sol.forces[0], [0, 0, -weight])
    assert np.allclose(sol.tip_position, [0, 0, -1.0])


@pytest.mark.parametrize("name", trajectories.NAMES)
@pytest.mark.parametrize("load", LOADS)
def test_ik_reaches_every_point_and_is_a_true_equilibrium(robot, name, load):
    points = trajectories.by_name(name)
    assert points.shape == (60, 3)
    results = robot.track(points, load=load)
    for p, r in zip(points, results, strict=True):
        assert r.reached, r.message
        assert r.tip_miss < 1e-9
        assert np.linalg.norm(r.tip_position - p) < 1e-9
        assert robot.within_bounds(r.rest_curvature)
    # A fresh forward solve from the straight rod with the returned actuation
    # lands on the same tip (every 6th point, to keep the suite fast).
    for p, r in list(zip(points, results, strict=True))[::6]:
        fresh = softspine.solve(robot.scene(r.rest_curvature, load=load), n_elements=20)
        assert fresh.converged and fresh.stable
        assert np.linalg.norm(fresh.tip_position - p) < 1e-9
        assert np.allclose(robot.muscle_lengths(r.rest_curvature), r.muscle_lengths)
        assert np.allclose(robot.inflation_times(r.muscle_lengths), r.inflation_times)


def test_minimum_norm_choice_among_solutions(robot):
    target = trajectories.circle()[7]
    plain = robot.inverse(target, load=0.03)
    other_reference = np.tile([[2.0, -1.0]], (robot.sections, 1))
    other = robot.inverse(target, load=0.03, reference=other_reference)
    assert plain.reached and other.reached
    # Two different actuations reach the same target ...
    assert np.abs(plain.rest_curvature - other.rest_curvature).max() > 0.1
    # ... and each is the closer one to its own reference.
    assert np.linalg.norm(plain.rest_curvature) < np.linalg.norm(other.rest_curvature)
    assert np.linalg.norm(other.rest_curvature - other_reference) < np.linalg.norm(
        plain.rest_curvature - other_reference
    )


def test_direction_can_be_prescribed_too(robot):
    target = np.array([0.1, 0.05, -0.9])
    direction = np.array([0.3, 0.0, -1.0])
    r = robot.inverse(target, load=0.03, direction=direction)
    assert r.reached, r.message
    q = r.solution.tip_quaternion
    w, x, y, z = q
    tangent = np.array([2 * (x * z + w * y), 2 * (y * z - w * x), w * w - x * x - y * y + z * z])
    assert np.allclose(tangent, direction / np.linalg.norm(direction), atol=1e-9)


def test_unreachable_target_returns_the_closest_tip_and_says_so(robot):
    r = robot.inverse([1.0, 0.0, -1.0], load=0.03)
    assert not r.reached and "not reached" in r.message
    assert r.tip_miss == pytest.approx(np.linalg.norm(r.tip_position - [1.0, 0.0, -1.0]))
    # Closer than the hanging rod, within the muscles' range.
    assert r.tip_miss < 0.5 * math.sqrt(2.0)
    assert robot.within_bounds(r.rest_curvature)


def test_ignoring_the_load_misses_by_centimetres(robot):
    """Measured, not assumed: the geometric strategy (weight and load ignored),
    and an IK done for 0 g then used with 60 g."""
    points = trajectories.circle()
    geometric = robot.track(points, load=0.06, strategy="geometric")
    miss = np.array([r.tip_miss for r in geometric])
    assert miss.min() > 0.01, miss.min()
    for_zero = robot.track(points, load=0.0)
    loaded = [robot.forward(r.rest_curvature, load=0.06) for r in for_zero]
    miss_load = np.array(
        [np.linalg.norm(s.tip_position - p) for s, p in zip(loaded, points, strict=True)]
    )
    assert miss_load.min() > 0.005, miss_load.min()


@pytest.mark.parametrize(
    "data,key",
    [
        ({"sections": 0}, "sections"),
        ({"length": -1.0}, "length"),
        ({"stiffness": {"kx": 1.0, "ky": -1.0, "kz": 1.0}}, "stiffness.ky"),
        ({"muscle_length_range": [0.1, 0.05]}, "muscle_length_range"),
        ({"muscle_angles": [0, 0, 0]}, "muscle_angles"),
        ({"colour": "red"}, "colour"),
        ({"n_elements": 15}, "n_elements"),
    ],
)
def test_bad_robot_is_refused_by_field(data, key):
    with pytest.raises(ValueError, match=f"^{key}:"):
        Robot(data)


def test_bad_ik_arguments(robot):
    with pytest.raises(ValueError, match="^target:"):
        robot.inverse([0.0, math.nan, -0.9])
    with pytest.raises(ValueError, match="^load:"):
        robot.inverse([0.0, 0.0, -0.9], load=-0.01)
    with pytest.raises(ValueError, match="^strategy:"):
        robot.inverse([0.0, 0.0, -0.9], strategy="magic")
    with pytest.raises(ValueError, match="^reference:"):
        robot.inverse([0.0, 0.0, -0.9], reference=np.zeros((3, 2)))
    with pytest.raises(ValueError, match="^rest_curvature:"):
        robot.scene(np.zeros((4, 2)))
