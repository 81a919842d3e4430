"""The solver against independent references: closed forms (Bisshopp-Drucker,
end-moment arcs, piecewise arcs) and second-order convergence as n doubles."""

from __future__ import annotations

import math

import numpy as np
import pytest

import softspine
from softspine.scenes import cantilever, end_moment

from closed_forms import BISSHOPP_DRUCKER, arc_chain_tip, observed_orders, quat_to_matrix

NS = (20, 40, 80)


def tip_errors(scene, exact_tip, method="newton", require_stable=True):
    errors = []
    for n in NS:
        sol = softspine.solve(scene, n_elements=n, method=method, check=True)
        assert sol.stable or not require_stable, sol.message
        errors.append(np.linalg.norm(sol.tip_position - exact_tip))
    return errors


def assert_second_order(errors, length=1.0, finest_bound=True):
    orders = observed_orders(errors)
    assert np.all((orders > 1.9) & (orders < 2.1)), f"orders {orders}, errors {errors}"
    if finest_bound:
        assert errors[-1] < 1e-3 * length, errors


@pytest.mark.parametrize("alpha", sorted(BISSHOPP_DRUCKER))
def test_bisshopp_drucker_cantilever(alpha):
    deflection, shortening, angle = BISSHOPP_DRUCKER[alpha]
    exact = np.array([deflection, 0.0, 1.0 - shortening])
    assert_second_order(tip_errors(cantilever(alpha), exact))
    sol = softspine.solve(cantilever(alpha), n_elements=160)
    tangent = quat_to_matrix(sol.tip_quaternion)[:, 2]
    assert math.atan2(tangent[0], tangent[2]) == pytest.approx(angle, abs=2e-4)
    # Deflection stays in the plane of the load.
    assert abs(sol.tip_position[1]) < 1e-12


@pytest.mark.parametrize("turns", [0.25, 0.5, 1.0])
def test_end_moment_gives_an_arc(turns):
    """Tip of an arc of curvature M/EI bent about world y: x = (1 - cos kL)/k, z = sin(kL)/k."""
    k = 2 * math.pi * turns
    exact = np.array([(1 - math.cos(k)) / k, 0.0, math.sin(k) / k])
    # Not asserted stable: past M = (pi / 2L) sqrt(EI GJ) (a quarter turn here) the
    # planar arc of a round rod is laterally (out of plane) unstable.
    errors = tip_errors(end_moment(turns), exact, require_stable=False)
    # The full roll-up is the one case where n = 80 is not within 1e-3 L: the
    # model's own error is 1.7e-2 L at n = 20 (MODEL.md), so 1.03e-3 L at n = 80.
    # It is checked at n = 160 instead (and its order at 20, 40, 80 like the others).
    assert_second_order(errors, finest_bound=turns < 1.0)
    if turns == 1.0:
        sol = softspine.solve(end_moment(1.0), n_elements=160, check=True)
        assert np.linalg.norm(sol.tip_position) < 1e-3
        # The tip tangent comes back to +z, its angle error also falls as n^-2.
        angle_errors = []
        for n in (40, 80, 160):
            t = quat_to_matrix(softspine.solve(end_moment(1.0), n_elements=n).tip_quaternion)[:, 2]
            angle_errors.append(abs(math.atan2(t[0], t[2])))
        orders = observed_orders(angle_errors)
        assert np.all((orders > 1.9) & (orders < 2.1)), angle_errors


def test_end_moment_curvature_is_uniform():
    sol = softspine.solve(end_moment(0.5), n_elements=40)
    r = sol.positions
    # Every node of an arc lies on one circle: centre at (1/k, 0, 0), radius 1/k.
    k = math.pi
    radius = np.linalg.norm(r - np.array([1 / k, 0, 0]), axis=1)
    assert np.ptp(radius) < 1e-3


@pytest.mark.parametrize(
    "rest_curvature,base",
    [
        ([[0.0, 2.0], [1.5, 0.0], [-1.0, -1.0]], [1.0, 0.0, 0.0, 0.0]),
        ([[3.0, -1.0], [0.0, 0.0], [-2.0, 4.0], [1.0, 1.0], [0.5, -3.0]], [0.0, 1.0, 0.0, 0.0]),
        ([[6.0, 0.0]], [0.9238795325112867, 0.0, 0.3826834323650898, 0.0]),
    ],
)
def test_piecewise_rest_curvature_gives_exact_arcs(rest_curvature, base):
    n_sections = len(rest_curvature)
    scene = {
        "length": 0.7,
        "stiffness": {"kx": 0.3, "ky": 0.5, "kz": 0.2},
        "rest_curvature": rest_curvature,
        "base_quaternion": base,
    }
    exact, _ = arc_chain_tip(rest_curvature, 0.7, quat_to_matrix(base))
    errors = []
    for n in (4 * n_sections * 5, 8 * n_sections * 5, 16 * n_sections * 5):
        sol = softspine.solve(scene, n_elements=n, check=True)
        errors.append(np.linalg.norm(sol.tip_position - exact))
    assert_second_order(errors, length=0.7)
