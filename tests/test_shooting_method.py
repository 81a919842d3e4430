"""method="shooting" (RK4 on the rod equations, Newton on the base wrench)
against the tight-tolerance SciPy shooting references of the continuous rod:
the whole backbone converges at order 4, the reactions of held tips too."""

from __future__ import annotations

import re

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


@pytest.mark.slow
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


# Random scenes (tools/scale_statistics.py, seed 11, scenes 147 and 313) on
# which the direct shooting attempt converged to an unstable equilibrium
# (energy 5.1 and 1.7 J against 0.027 and 0.33 J for the stable one).
UNSTABLE_BRANCH_SCENES = [
    {"length": 1.348662661243758,
     "stiffness": {"kx": 0.4087191205237548, "ky": 1.1392367909114356, "kz": 0.19467126536844037},
     "rest_curvature": [[0.46991548194044935, -0.6611462826590128],
                        [0.4780966519635226, -3.79582173909425],
                        [0.7005775248332992, 4.051693585962575],
                        [0.07483380842667575, 1.3987845376478631]],
     "gravity": {"linear_density": 0.07614944085328831,
                 "vector": [-1.586791797007164, -9.033190268823589, -3.4813309753859394]},
     "tip_force": [0.29177179183794594, -0.759064439498569, -0.8445532525467868],
     "tip_moment": [0.14210450603745386, 0.2002213831771328, -0.8949376578322207]},
    {"length": 0.7179295621404197,
     "stiffness": {"kx": 1.2122168245732263, "ky": 0.425937142471721, "kz": 0.41189361253047857},
     "rest_curvature": [[-3.6970403833805325, -2.079830802376986],
                        [2.7866164459002105, 2.091576662575475],
                        [5.588323154062628, 1.5109966781317985],
                        [0.5778206359626583, 1.1531754215273151]],
     "gravity": {"linear_density": 0.038698731973431655,
                 "vector": [-0.8756382563095324, -2.5517621574110003, -9.43174785159635]},
     "tip_force": [1.8245060223146017, -3.223495334320462, -1.9107953346219824],
     "tip_moment": [-0.2721240669222711, 0.2354442628188846, -0.4585058239717305],
     "base_quaternion": [-0.5080153126208642, 0.05144493610637062,
                         -0.015422882759117214, 0.8596720277984713]},
]


@pytest.mark.parametrize("scene", UNSTABLE_BRANCH_SCENES)
def test_an_unstable_direct_answer_gives_way_to_the_load_path(scene):
    shot = softspine.solve(scene, n_elements=96, method="shooting", check=True)
    newton = softspine.solve(scene, n_elements=96, scheme="fe4", check=True)
    assert shot.stable and newton.stable
    assert np.abs(shot.positions - newton.positions).max() < 1e-6 * scene["length"]


@pytest.mark.parametrize(
    "scene",
    [
        # A buckled cantilever and a heavy precurved rod: shooting's path jumped
        # to unstable equilibria 0.8 and 1.5 L from the load path's (3e30b16).
        {"length": 1.0, "stiffness": {"kx": 1.0, "ky": 0.7, "kz": 0.7},
         "tip_force": [0.002, 0.2, -3.0]},
        {"length": 2.0, "stiffness": {"kx": 2.0, "ky": 2.0, "kz": 4.0},
         "gravity": {"linear_density": 2.0, "vector": [0.0, 0.0, -3.0]},
         "rest_curvature": [[0.06, 0.02]]},
    ],
)
def test_shooting_follows_the_load_path_to_newtons_equilibrium(scene):
    newton = softspine.solve(scene, n_elements=20, scheme="fe4", check=True)
    shot = softspine.solve(scene, n_elements=20, method="shooting", check=True)
    assert newton.stable and shot.stable
    # Both fourth order at the nodes: the same equilibrium to 1e-5 L.
    assert np.abs(shot.positions - newton.positions).max() < 1e-5 * scene["length"]


def test_shooting_says_when_it_cannot_follow_the_load_path():
    # Reported converged on an unstable equilibrium 1.1 L from Newton's (3e30b16).
    scene = {"length": 0.5, "stiffness": {"kx": 0.2, "ky": 0.2, "kz": 0.19},
             "tip_force": [-11.0, 5.5, -29.0], "rest_curvature": [[1.1, -4.1]]}
    newton = softspine.solve(scene, n_elements=20, check=True)
    shot = softspine.solve(scene, n_elements=20, method="shooting")
    if shot.converged:
        assert np.abs(shot.positions - newton.positions).max() < 0.05 * scene["length"]
    else:
        assert "could not follow the load path" in shot.message
        assert re.search(r"load scale 0\.\d+ of 1", shot.message), shot.message


def test_shooting_crosses_where_the_loading_itself_loses_stability():
    # A dead end moment of 2 pi EI/L rolls the rod up past half a turn, where
    # the path loses stability: as the finite-element driver, shooting ends
    # there, unstable (it refused once it kept stability at every step).
    scene = {"length": 1.0, "stiffness": {"kx": 1.0, "ky": 1.0, "kz": 1.0},
             "tip_moment": [0.0, 2 * np.pi, 0.0]}
    shot = softspine.solve(scene, n_elements=40, method="shooting", check=True)
    assert not shot.stable
    np.testing.assert_allclose(shot.tip_position, [0.0, 0.0, 0.0], atol=1e-6)


MOMENT_BASE = {
    "length": 1.0,
    "stiffness": {"kx": 1.0, "ky": 2.0, "kz": 0.7},
    "base_quaternion": [0.7071067811865476, 0.0, 0.7071067811865476, 0.0],
    "gravity": {"linear_density": 0.5, "vector": [0.0, 0.0, -9.81]},
}
MOMENT_SCENES = {
    "point moment": {**MOMENT_BASE, "point_loads": [
        {"s": 0.5, "force": [0.0, 0.5, 0.0], "moment": [0.3, -0.8, 0.4]}]},
    "distributed moment": {**MOMENT_BASE, "distributed_moment": [0.2, 0.6, -0.5]},
    "tip force off the tip": {**MOMENT_BASE, "tip_force": [0.0, 1.0, -2.0],
                              "tip_force_offset": [0.05, 0.0, 0.1]},
    "pinned, point moment": {**MOMENT_BASE, "point_loads": [{"s": 0.5, "moment": [0.0, 1.5, 0.0]}],
                             "tip": {"type": "pinned", "position": [0.8, 0.1, -0.3]}},
}


def shooting_errors_against_fe4(
    scene: dict, lowest_order: float, sizes: tuple[int, ...] = (10, 20, 40), fine_n: int = 640
) -> tuple[softspine.Solution, list[float]]:
    """fe4 at n = `fine_n` and shooting's largest node error against it at
    n = `sizes` (each converged and stable), whose observed orders lie
    between `lowest_order` and 4.4."""
    fine = softspine.solve(scene, n_elements=fine_n, scheme="fe4")
    assert fine.converged
    errors = []
    for n in sizes:
        sol = softspine.solve(scene, n_elements=n, method="shooting")
        assert sol.converged and sol.stable, sol.message
        errors.append(np.abs(sol.positions - fine.positions_at(sol.arc_length)).max())
    orders = observed_orders(errors)
    assert np.all((orders > lowest_order) & (orders < 4.4)), (orders, errors)
    return fine, errors


MAGNET_SCENES = {
    "magnetised rod": {**MOMENT_BASE, "magnetization": [[0.0, 0.0, 0.2]],
                       "magnetic_field": [0.0, 5.0, 10.0]},
    "tip magnet": {**MOMENT_BASE, "tip_magnet": [0.1, 0.0, 0.3], "magnetic_field": [3.0, 4.0, 0.0]},
    "two sections and a tip magnet": {
        **MOMENT_BASE, "magnetization": [[0.0, 0.0, 0.2], [0.1, 0.0, -0.2]],
        "tip_magnet": [0.0, 0.0, 0.1], "magnetic_field": [0.0, 5.0, 2.0]},
}


@pytest.mark.parametrize("name", list(MAGNET_SCENES))
def test_shooting_models_magnets_at_fourth_order(name):
    # A magnetised rod in a uniform field carries (R mu) x B per length and
    # a tip magnet (R mu_tip) x B at the tip: moments that turn with the rod
    # (refused before). Against fe4 at n = 640, whose magnets are potentials
    # (-B . R mu): order 4 (measured ratios 13.7 to 16.5 a halving); the
    # default's accuracy on demand shoots them.
    scene = MAGNET_SCENES[name]
    fine, errors = shooting_errors_against_fe4(scene, 3.6)
    assert errors[-1] < 3e-8, errors  # measured 7.1e-9 to 1.5e-8 at n = 40
    # The field moves the tip out of the plane gravity alone bends it in.
    assert abs(fine.tip_position[1]) > 0.05
    chosen = softspine.solve(scene, tol=1e-6)
    assert chosen.converged and chosen.scheme == "rk4"


SECTION_SCENES = {
    # Three sections of their own stiffness and density (test_sections.py's
    # rod without its tendon), one with a moment of its own.
    "stiffness and density": {
        "length": 0.9, "stiffness": {"kx": 0.5, "ky": 0.6, "kz": 0.4},
        "rest_curvature": [[0.4, -0.2], [0.0, 0.0], [-0.5, 0.3]],
        "sections": [
            {"stiffness": {"kx": 1.5, "ky": 1.2, "kz": 1.0}, "linear_density": 0.6},
            {"distributed_moment": [0.0, 0.05, -0.02]},
            {"stiffness": {"kx": 0.2, "ky": 0.25, "kz": 0.15}, "linear_density": 0.1},
        ],
        "gravity": {"linear_density": 0.3, "vector": [0.0, 0.2, -9.81]},
        "tip_force": [0.3, -0.1, -0.2],
    },
    # Sections of their own lengths: elements of three sizes, a point load
    # on a node of the longest.
    "lengths": {
        **MOMENT_BASE, "rest_curvature": [[0.5, 0.0], [0.0, -0.8], [1.0, 0.3]],
        "sections": [{"length": 0.2}, {"length": 0.5, "stiffness": {"kx": 3, "ky": 3, "kz": 2}},
                     {"length": 0.3, "linear_density": 0.2}],
        "point_loads": [{"s": 0.45, "force": [0.0, 0.3, 0.2]}],
    },
}


@pytest.mark.parametrize("name", list(SECTION_SCENES))
def test_shooting_models_sections_of_their_own_at_fourth_order(name):
    # Each element integrates with its section's stiffness, density and
    # moment over its own length (refused before). Against fe4 at n = 768,
    # at the shot's own node arcs (a shot's Solution gave equal elements
    # whatever the sections' lengths: 0.13 m off): order 4 (measured 3.95
    # to 4.02), 7.7e-10 and 1.2e-9 m at n = 48; the default's accuracy on
    # demand shoots them.
    scene = SECTION_SCENES[name]
    _, errors = shooting_errors_against_fe4(scene, 3.6, (12, 24, 48), 768)
    assert errors[-1] < 5e-9, errors
    chosen = softspine.solve(scene, tol=1e-6)
    assert chosen.converged and chosen.scheme == "rk4", chosen.scheme


@pytest.mark.parametrize("name", list(MOMENT_SCENES))
def test_shooting_models_moments_and_a_tip_force_off_the_tip_at_fourth_order(name):
    # Dead moments (world frame) jump the internal moment at a point load's
    # node and turn it along the rod (m' = n x r' - l); a tip force at an
    # offset c adds (R c) x F at the tip. Refused before. Against the
    # discrete potential's fe4 at n = 640 (moments as virtual work, another
    # discretisation): order 4 (measured ratios 15.7 to 20.2 a halving).
    scene = MOMENT_SCENES[name]
    _, errors = shooting_errors_against_fe4(scene, 3.7)
    assert errors[-1] < 3e-7, errors  # measured 2.0e-8 to 1.7e-7 at n = 40
    # Accuracy on demand now shoots these where the tip is free.
    chosen = softspine.solve(scene, tol=1e-6)
    assert chosen.converged
    assert (chosen.scheme == "rk4") == ("tip" not in scene), chosen.scheme
