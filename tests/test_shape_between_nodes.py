"""The shape between the nodes (`Solution.positions_at`, `rotations_at`)
against the continuous rod (SciPy shooting) at stations that are no node:
positions converge at the scheme's order (2 for fd2, 4 for fe4)."""

from __future__ import annotations

import pickle

import numpy as np
import pytest

import softspine

from validation import shooting

SCENE = {
    "length": 1.0,
    "stiffness": {"kx": 1.0, "ky": 1.3, "kz": 0.8},
    "rest_curvature": [[0.7, -0.4]],
    "gravity": {"linear_density": 0.3, "vector": [0.0, 0.4, -9.81]},
    "tip_force": [0.6, -0.3, -0.9],
    "tip_moment": [0.1, 0.2, -0.1],
}
# Stations at 0.37, 0.53 and 0.81 L: a node of none of the meshes below.
STATIONS = [37, 53, 81]


@pytest.fixture(scope="module")
def reference():
    return shooting.solve(SCENE, rtol=1e-12, n_samples=101)


def turn(q, r):
    """Angle between rotations given as rows of unit quaternions (the angle
    of conj(q) r, accurate down to round-off, unlike an arccos)."""
    q, r = np.asarray(q), np.asarray(r)
    w = np.abs(np.sum(q * r, axis=-1))
    v = q[..., :1] * r[..., 1:] - r[..., :1] * q[..., 1:] - np.cross(q[..., 1:], r[..., 1:])
    return 2.0 * np.arctan2(np.linalg.norm(v, axis=-1), w)


@pytest.mark.parametrize(
    "scheme, counts, order",
    [("fd2", [8, 16, 32, 64], 2.0), ("fe4", [4, 8, 16, 32], 4.0)],
)
def test_positions_between_nodes_converge_at_the_schemes_order(reference, scheme, counts, order):
    s = reference["s"][STATIONS]
    position_errors, rotation_errors = [], []
    for n in counts:
        sol = softspine.solve(SCENE, n_elements=n, scheme=scheme, residual_tol=1e-14)
        assert not np.any(np.isclose(np.outer(s, np.ones(n + 1)), sol.arc_length))
        position_errors.append(np.abs(sol.positions_at(s) - reference["positions"][STATIONS]).max())
        rotation_errors.append(turn(sol.rotations_at(s), reference["quaternions"][STATIONS]).max())
    observed = np.log2(np.array(position_errors[:-1]) / position_errors[1:])
    assert observed[-1] == pytest.approx(order, abs=0.15), position_errors
    # Rotations: the scheme's interpolant at its order too (fe4: through the
    # element's nodes, its internal node and its neighbours'; the element's
    # own quadratic alone measured 2.6).
    turns = np.log2(np.array(rotation_errors[:-1]) / rotation_errors[1:])
    assert turns[-1] == pytest.approx(order, abs=0.2), rotation_errors


@pytest.mark.parametrize("scheme", ["fd2", "fe4"])
def test_at_the_nodes_the_shape_is_the_nodes(scheme):
    sol = softspine.solve(SCENE, n_elements=8, scheme=scheme)
    np.testing.assert_allclose(sol.positions_at(sol.arc_length), sol.positions, atol=1e-14)
    q = sol.rotations_at(sol.arc_length)
    assert turn(q, sol.quaternions).max() < 1e-7
    # Any shape of stations; the shape survives a round trip through a dict.
    grid = np.linspace(0.0, 1.0, 12).reshape(3, 4)
    assert sol.positions_at(grid).shape == (3, 4, 3)
    assert sol.rotations_at(0.5).shape == (4,)
    again = pickle.loads(pickle.dumps(sol))
    np.testing.assert_array_equal(again.positions_at(grid), sol.positions_at(grid))


@pytest.mark.parametrize("s, name", [([0.2, 1.5], "s[1]"), ([np.nan], "s[0]"), ([-0.1], "s[0]")])
def test_stations_off_the_rod_are_refused_by_name(s, name):
    sol = softspine.solve(SCENE, n_elements=8)
    with pytest.raises(ValueError, match=name.replace("[", r"\[")):
        sol.positions_at(s)
    with pytest.raises(ValueError, match=name.replace("[", r"\[")):
        sol.rotations_at(s)


def test_another_n_s_arc_lengths_of_the_same_rod_are_on_it():
    # L is a sum of section lengths, which rounds differently at another n: a
    # campaign's 1 m rod of three sections had L = 0.9999999999999999 at
    # n = 960 and its n = 18 solution's last arc length 1.0, refused as off
    # the rod.
    scene = {"length": 1.0, "stiffness": {"kx": 3.9, "ky": 2.0, "kz": 3.1},
             "rest_curvature": [[2.28, -1.53], [-0.32, 2.21], [-1.61, -1.50]],
             "sections": [{"length": 0.19680520214782107}, {"length": 0.353907749548695},
                          {"length": 0.4492870483034838}]}
    coarse = softspine.solve(scene, n_elements=18, method="shooting")
    fine = softspine.solve(scene, n_elements=960, method="shooting")
    assert coarse.arc_length[-1] > fine.length  # by round-off
    np.testing.assert_allclose(fine.positions_at(coarse.arc_length)[-1], fine.positions[-1],
                               rtol=0, atol=1e-15)
    np.testing.assert_allclose(fine.rotations_at(coarse.arc_length[-1:])[0],
                               fine.quaternions[-1], rtol=0, atol=1e-15)
    with pytest.raises(ValueError, match=r"s\[0\]"):
        fine.positions_at([fine.length * (1 + 1e-12)])


def test_a_stored_fourth_order_solution_without_internal_nodes_says_so():
    data = softspine.solve(SCENE, n_elements=8, scheme="fe4").to_dict()
    del data["internal_quaternions"]
    old = softspine.Solution.from_dict(data)
    with pytest.raises(ValueError, match="internal_quaternions"):
        old.positions_at([0.5])


def test_the_breaks_travel_with_the_solution_and_older_dicts_interpolate_each_element():
    two_sections = {**SCENE, "rest_curvature": [[0.7, -0.4], [-0.5, 0.2]],
                    "point_loads": [{"s": 0.25, "force": [0.1, 0.0, 0.0]}]}
    sol = softspine.solve(two_sections, n_elements=8, scheme="fe4")
    data = sol.to_dict()
    # The point load's node and the sections' joint.
    assert data["breaks"] == [2, 4]
    s = np.linspace(0.0, 1.0, 23)
    again = softspine.Solution.from_dict(data)
    np.testing.assert_array_equal(again.rotations_at(s), sol.rotations_at(s))
    # A dict of an earlier version: every node a break, each element's own
    # quadratic (third order), the nodes still met.
    del data["breaks"]
    older = softspine.Solution.from_dict(data)
    assert turn(older.rotations_at(sol.arc_length), sol.quaternions).max() < 1e-12
    assert 0.0 < turn(older.rotations_at(s), sol.rotations_at(s)).max() < 1e-3
    for bad, reason in (([0], "interior"), ([8], "interior"), ([1.5], "node indices")):
        data["breaks"] = bad
        with pytest.raises(ValueError, match=r"solution\.breaks.*" + reason):
            softspine.Solution.from_dict(data)
