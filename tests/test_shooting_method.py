"""method="shooting" (RK4 on the rod equations, Newton on the base wrench)
against the tight-tolerance SciPy shooting references of the continuous rod:
the whole backbone converges at order 4, the reactions of held tips too."""

from __future__ import annotations

import numpy as np
import pytest
from test_held_references import ROD, held_scenes

import softspine

from closed_forms import observed_orders
from validation import shooting, shooting_held

FREE_3D = {
    "length": 1.0,
    "stiffness": {"kx": 1.0, "ky": 1.25, "kz": 0.8},
    "rest_curvature": [[2.0, -1.0], [-1.5, 3.0], [0.5, 2.5], [-2.0, -2.0], [1.0, 0.0]],
    "gravity": {"linear_density": 0.2, "vector": [3.0, -2.0, -9.81]},
    "tip_force": [0.4, 0.3, -0.2],
    "tip_moment": [0.1, -0.2, 0.05],
}
ELEMENTS = (10, 20, 40)


def whole_backbone_errors(scene, exact_positions_at, elements=ELEMENTS):
    errors = []
    for n in elements:
        sol = softspine.solve(scene, n_elements=n, method="shooting", check=True)
        exact = exact_positions_at(n)
        errors.append(np.abs(sol.positions - exact).max() / scene["length"])
    return np.array(errors), sol


def test_free_rod_whole_backbone_is_fourth_order():
    def exact(n):
        return shooting.solve(FREE_3D, n_samples=n + 1)["positions"]

    errors, sol = whole_backbone_errors(FREE_3D, exact)
    orders = observed_orders(errors)
    assert np.all((orders > 3.7) & (orders < 4.3)), (orders, errors)
    assert errors[-1] < 1e-6, errors
    assert sol.stable and sol.status == "converged"
    # The base force is explicit (the sum of the loads): exact to round-off.
    ref = shooting.solve(FREE_3D, n_samples=5)
    assert np.allclose(sol.forces[0], ref["base_force"], atol=1e-12)


@pytest.mark.parametrize("kind", ["pinned", "clamped"])
def test_held_tips_and_reactions_are_fourth_order(kind):
    scene = held_scenes()[kind]
    # From n = 20: at n = 10 the errors of the held rods are not yet asymptotic.
    elements = (20, 40, 80)
    exact = {n: shooting_held.solve(scene, n_samples=n + 1) for n in elements}
    errors, _ = whole_backbone_errors(scene, lambda n: exact[n]["positions"], elements)
    force_errors, moment_errors = [], []
    for n in elements:
        sol = softspine.solve(scene, n_elements=n, method="shooting", check=True)
        assert sol.stable
        force_errors.append(
            np.linalg.norm(sol.tip_reaction_force - exact[n]["tip_reaction_force"])
        )
        if kind == "clamped":
            moment_errors.append(
                np.linalg.norm(sol.tip_reaction_moment - exact[n]["tip_reaction_moment"])
            )
    for e in (errors, force_errors, moment_errors):
        if len(e) == 0:
            continue
        orders = observed_orders(e)
        assert np.all((orders > 3.7) & (orders < 4.3)), (orders, e)


def test_shooting_refuses_guides_by_name():
    scene = {**ROD, "guides": [{"s": 0.45, "position": [0.0, 0.1, -0.4]}]}
    with pytest.raises(ValueError, match="method.*guides"):
        softspine.solve(scene, method="shooting")


def test_shooting_reports_an_exhausted_budget():
    scene = {"length": 1.0, "stiffness": {"kx": 1, "ky": 1, "kz": 1}, "tip_force": [10, 0, 0]}
    sol = softspine.solve(scene, method="shooting", max_iterations=1)
    assert sol.status == "iteration_limit" and not sol.stable
    assert sol.iterations <= 1
