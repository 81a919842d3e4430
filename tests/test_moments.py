"""Point moments and distributed moments (dead, world frame) against the
continuous rod (tests/wrench_reference.py, SciPy shooting with the wrenches'
jumps): positions converge at the scheme's order at stations that are no
node, and their derivatives are those of whole solves."""

from __future__ import annotations

import copy

import numpy as np
import pytest
from wrench_reference import WrenchRod

import softspine

SCENE = {
    "length": 1.0,
    "stiffness": {"kx": 1.0, "ky": 1.3, "kz": 0.8},
    "rest_curvature": [[0.7, -0.4], [-0.3, 0.5]],
    "sections": [{}, {"distributed_moment": [0.3, -0.5, 0.2]}],
    "gravity": {"linear_density": 0.3, "vector": [0.0, 0.4, -9.81]},
    "distributed_moment": [-0.2, 0.4, 0.1],
    "tip_force": [0.6, -0.3, -0.9],
    "tip_moment": [0.1, 0.2, -0.1],
    "point_loads": [{"s": 0.5, "force": [0.5, 0.2, -0.4], "moment": [0.3, -0.2, 0.25]}],
}
# 0.37, 0.53 and 0.81 L are a node of no mesh below; 0.5 L holds the point load.
STATIONS = [0.37, 0.5, 0.53, 0.81, 1.0]


@pytest.fixture(scope="module")
def reference():
    return WrenchRod(SCENE).solve(STATIONS)


@pytest.mark.slow
@pytest.mark.parametrize(
    "scheme, counts, order",
    [("fd2", [8, 16, 32, 64], 2.0), ("fe4", [4, 8, 16, 32], 4.0)],
)
def test_wrenches_converge_at_the_schemes_order(reference, scheme, counts, order):
    positions, _ = reference
    errors = []
    for n in counts:
        sol = softspine.solve(SCENE, n_elements=n, scheme=scheme, residual_tol=1e-14)
        assert sol.converged and sol.stable
        errors.append(np.abs(sol.positions_at(STATIONS) - positions).max())
    observed = np.log2(np.array(errors[:-1]) / errors[1:])
    assert observed[-1] == pytest.approx(order, abs=0.1), errors
    assert errors[-1] < {"fd2": 5e-4, "fe4": 1e-7}[scheme]


def test_rotations_between_nodes_converge_at_the_schemes_order_across_breaks(reference):
    # Sections of their own moment and rest curvature and a point wrench at
    # 0.5 L: the shape between the nodes is not interpolated across them.
    from test_shape_between_nodes import turn

    _, quaternions = reference
    for scheme, counts, order in [("fd2", [16, 32, 64], 2.0), ("fe4", [8, 16, 32], 4.0)]:
        errors = []
        for n in counts:
            sol = softspine.solve(SCENE, n_elements=n, scheme=scheme, residual_tol=1e-14)
            errors.append(turn(sol.rotations_at(STATIONS), quaternions).max())
        observed = np.log2(np.array(errors[:-1]) / errors[1:])
        assert observed[-1] == pytest.approx(order, abs=0.2), (scheme, errors)


def test_every_moment_matters(reference):
    positions, _ = reference
    for strip in ("distributed_moment", "sections", "point_loads"):
        scene = copy.deepcopy(SCENE)
        if strip == "point_loads":
            del scene["point_loads"][0]["moment"]
        else:
            del scene[strip]
        sol = softspine.solve(scene, n_elements=32, scheme="fe4")
        assert np.abs(sol.positions_at(STATIONS) - positions).max() > 1e-2, strip


def test_a_point_moment_at_the_tip_is_a_tip_moment():
    at_tip = {**SCENE, "point_loads": [{"s": 1.0, "moment": [0.3, -0.2, 0.25]}]}
    as_tip = {**SCENE, "point_loads": [], "tip_moment": [0.4, 0.0, 0.15]}
    at_tip["tip_moment"] = [0.1, 0.2, -0.1]
    for scheme in ("fd2", "fe4"):
        a = softspine.solve(at_tip, n_elements=16, scheme=scheme)
        b = softspine.solve(as_tip, n_elements=16, scheme=scheme)
        np.testing.assert_allclose(a.positions, b.positions, rtol=0, atol=1e-12)


@pytest.mark.parametrize("scheme", ["fd2", "fe4"])
def test_moment_sensitivities_are_those_of_whole_solves(scheme):
    names = ["point_loads[0].moment[1]", "distributed_moment[0]",
             "sections[1].distributed_moment[2]", "tip_moment[2]"]
    solver = softspine.Solver(SCENE, n_elements=16, scheme=scheme)
    solver.solve(check=True)
    sens = solver.sensitivity(names).tip_position

    def tip(path, delta):
        scene = copy.deepcopy(SCENE)
        box, key = scene, path
        parts = path.replace("]", "").replace("[", ".").split(".")
        for p in parts[:-1]:
            box = box[int(p)] if p.isdigit() else box[p]
        key = int(parts[-1]) if parts[-1].isdigit() else parts[-1]
        box[key] += delta
        return softspine.solve(scene, n_elements=16, scheme=scheme,
                               residual_tol=1e-14).positions[-1]

    for j, name in enumerate(names):
        h = 1e-3
        # A five-point difference: truncation about h^4.
        fd = (-tip(name, 2 * h) + 8 * tip(name, h) - 8 * tip(name, -h)
              + tip(name, -2 * h)) / (12 * h)
        np.testing.assert_allclose(sens[:, j], fd, rtol=1e-7, atol=1e-9 * np.abs(fd).max(),
                                   err_msg=name)


def test_a_dead_moment_is_judged_stable_on_its_symmetric_part():
    # A rod rolled by a distributed moment about its bending axis: stable.
    sol = softspine.solve({"length": 1.0, "stiffness": {"kx": 1, "ky": 1, "kz": 1},
                           "distributed_moment": [2.0, 0.0, 0.0]}, n_elements=40)
    assert sol.converged and sol.stable
    # Planar: the moment at s is 2 (L - s) about x, the curvature with it.
    kappa = sol.curvatures[:, 0]
    s_mid = 0.5 * (sol.arc_length[1:] + sol.arc_length[:-1])
    np.testing.assert_allclose(kappa[1:-1], 2.0 * (1.0 - s_mid[1:-1]), atol=5e-3)


@pytest.mark.parametrize(
    "change, key",
    [
        ({"point_loads": [{"s": 0.5}]}, r"point_loads\[0\]: give a force"),
        ({"point_loads": [{"s": 0.5, "moment": [0, float("nan"), 0]}]},
         r"point_loads\[0\]\.moment"),
        ({"distributed_moment": [1, 2]}, "distributed_moment"),
        ({"sections": [{}, {"distributed_moment": "x"}]}, r"sections\[1\]\.distributed_moment"),
        ({"distributed_moment": [1e300, 0, 0]}, "distributed_moment"),
    ],
)
def test_bad_moments_are_refused_by_name(change, key):
    with pytest.raises(ValueError, match=key):
        softspine.Scene({**SCENE, **change})


def test_the_methods_without_moments_say_so():
    with pytest.raises(ValueError, match="moments"):
        softspine.solve(SCENE, method="paper")


@pytest.mark.parametrize("whole", [False, True])
def test_shooting_with_moments_meets_the_continuous_rod_at_fourth_order(whole):
    # Point and distributed moments in shooting (m' = n x r' - l, a jump at
    # the point load's node) against SciPy shooting with the wrenches' jumps;
    # the whole scene adds the rest curvature and the second section's own
    # distributed moment (refused before; measured ratios 16.4, 16.3).
    scene = SCENE if whole else {
        k: v for k, v in SCENE.items() if k not in ("sections", "rest_curvature")}
    positions, _ = WrenchRod(scene).solve(list(np.linspace(0.0, 1.0, 41)))
    errors = []
    for n in (10, 20, 40):
        sol = softspine.solve(scene, n_elements=n, method="shooting")
        assert sol.converged and sol.stable, sol.message
        errors.append(np.abs(sol.positions - positions[:: 40 // n]).max())
    ratios = [a / b for a, b in zip(errors, errors[1:], strict=False)]
    assert all(13.0 < r < 19.0 for r in ratios), (ratios, errors)
