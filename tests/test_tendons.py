"""Tendon-driven and magnetised rods against an independent reference:
shooting on the Cosserat rod with the Rucker-Webster tendon loads and the
field's moment (tests/tendon_reference.py), and the scene's input."""

from __future__ import annotations

import numpy as np
import pytest
from tendon_reference import solve_reference

import softspine

from closed_forms import observed_orders

L = 1.0
SCENE = {
    "length": L,
    "stiffness": {"kx": 0.5, "ky": 0.6, "kz": 0.4},
    "rest_curvature": [[0.5, -0.3], [-0.4, 0.8]],
    "gravity": {"linear_density": 0.3, "vector": [0.0, 0.2, -9.81]},
    "tip_force": [0.2, -0.1, 0.0],
    "tendons": [
        {"tension": 6.0, "offset": [0.012, 0.0], "end": 0.5},
        {"tension": 4.0, "offset": [0.0, 0.01], "twist": 3.0},
        {"tension": 2.5, "offset": [-0.008, -0.006], "twist": -1.5, "end": 0.75},
    ],
}


@pytest.fixture(scope="module")
def reference():
    """Node positions at s = i L / 32 (a helix, an anchor inside a section
    and one at a section end, rest curvature, gravity, a tip force)."""
    return solve_reference(SCENE, list(np.linspace(0, L, 33)), rtol=1e-10)


def errors(scheme, sizes, reference):
    out = []
    for n in sizes:
        sol = softspine.solve(SCENE, n_elements=n, scheme=scheme, residual_tol=1e-13)
        assert sol.converged and sol.stable, sol.message
        out.append(np.abs(sol.positions - reference[:: 32 // n]).max() / L)
    return out


@pytest.mark.slow
def test_both_schemes_converge_to_the_rucker_webster_rod_at_their_orders(reference):
    fd2 = errors("fd2", [8, 16, 32], reference)
    fe4 = errors("fe4", [4, 8, 16], reference)
    assert all(1.8 < p < 2.2 for p in observed_orders(fd2)), fd2
    assert all(3.6 < p < 4.4 for p in observed_orders(fe4)), fe4
    assert fe4[-1] < 1e-6, fe4


@pytest.mark.slow
def test_shooting_models_tendons_at_fourth_order(reference):
    # Shooting takes a tendon as part of the rod's constitutive law (its
    # potential, a function of the curvature: each stage solves for the
    # curvature whose moment is the internal one), the reference as Rucker
    # and Webster's loads on the rod: the same rod.
    errs = []
    for n in (8, 16, 32):  # (at n = 4 an element still turns too far: 3.5)
        sol = softspine.solve(SCENE, n_elements=n, method="shooting")
        assert sol.converged and sol.stable and sol.scheme == "rk4", sol.message
        errs.append(np.abs(sol.positions - reference[:: 32 // n]).max() / L)
    assert all(3.6 < p < 4.4 for p in observed_orders(errs)), errs
    assert errs[-1] < 5e-7, errs
    # Accuracy on demand keeps tendons on the discrete potential (a shot
    # solves for the curvature at every stage: 5 times fe4's time on the
    # tendon robot); shooting is there to be asked for.
    sol = softspine.solve(SCENE, tol=1e-6, check=True)
    assert sol.scheme == "fe4"
    assert softspine.solve(SCENE, tol=1e-6, method="shooting").scheme == "rk4"


def test_tendon_sensitivities_match_differences_of_solves():
    solver = softspine.Solver(SCENE, n_elements=16, residual_tol=1e-13)
    solver.solve(check=True)
    sens = solver.sensitivity(["tendons[0].tension", "tendons[1].tension"])
    h = 1e-4
    for j in range(2):
        tips = []
        for sign in (1, -1):
            data = softspine.Scene(SCENE).to_dict()
            data["tendons"][j]["tension"] += sign * h
            tips.append(softspine.solve(data, n_elements=16, residual_tol=1e-13).tip_position)
        fd = (tips[0] - tips[1]) / (2 * h)
        np.testing.assert_allclose(sens.tip_position[:, j], fd, atol=1e-7)


def test_tendons_round_trip_through_the_scene_dict():
    data = softspine.Scene(SCENE).to_dict()
    assert data["tendons"][1] == {"tension": 4.0, "offset": [0.0, 0.01], "twist": 3.0, "end": 1.0}
    assert softspine.Scene(data).to_dict() == data


@pytest.mark.parametrize(
    ("tendon", "message"),
    [
        ({"tension": -1.0, "offset": [0.01, 0]}, r"tendons\[0\].tension: .*cannot push"),
        ({"tension": float("nan"), "offset": [0.01, 0]}, r"tendons\[0\].tension"),
        ({"tension": 1.0, "offset": [0.01]}, r"tendons\[0\].offset"),
        ({"tension": 1.0, "offset": [0.01, 0], "end": 1.5}, r"tendons\[0\].end: must lie in"),
        ({"tension": 1.0, "offset": [0.01, 0], "pull": 2}, r"tendons\[0\]"),
        ({"offset": [0.01, 0]}, r"tendons\[0\].tension"),
    ],
)
def test_bad_tendons_are_refused_by_name(tendon, message):
    scene = {"length": 1, "stiffness": {"kx": 1, "ky": 1, "kz": 1}, "tendons": [tendon]}
    with pytest.raises(ValueError, match=message):
        softspine.solve(scene)


def test_an_anchor_off_the_nodes_and_methods_without_tendons_are_refused():
    scene = {
        "length": 1,
        "stiffness": {"kx": 1, "ky": 1, "kz": 1},
        "tendons": [{"tension": 1.0, "offset": [0.01, 0], "end": 0.33}],
    }
    with pytest.raises(ValueError, match=r"tendons\[0\].end"):
        softspine.solve(scene, n_elements=20)
    del scene["tendons"][0]["end"]
    with pytest.raises(ValueError, match="tendons"):
        softspine.solve(scene, method="paper")


ROUTED = {
    "stiffness": {"kx": 0.5, "ky": 0.6, "kz": 0.4},
    "rest_curvature": [[0.4, -0.2], [0.0, 0.0], [-0.5, 0.3]],
    "sections": [{"length": 0.2}, {"length": 0.45}, {"length": 0.25}],
    "gravity": {"linear_density": 0.3, "vector": [0.0, 0.2, -9.81]},
    "tendons": [
        # Through holes of its own in each section, helical in the second.
        {"tension": 2.0, "offset": [[0.01, 0.0], [0.0, 0.012], [-0.008, 0.004]],
         "twist": [0, 4.0, 0]},
        # Two sections, anchored at the second's end (s = 0.65).
        {"tension": 1.5, "offset": [[-0.01, 0.002], [0.006, -0.01]], "twist": 2.0, "end": 0.65},
    ],
}


@pytest.mark.slow
def test_tendons_routed_section_by_section_converge_to_the_rucker_webster_rod():
    """At a section's start such a tendon crosses the disk to its new hole:
    the reference bends it there (two point loads); the potential only
    changes where the routing is evaluated."""
    fine = softspine.solve(ROUTED, n_elements=48, residual_tol=1e-13)
    reference = solve_reference(ROUTED, list(fine.arc_length), rtol=1e-10)
    errors = {}
    for scheme, sizes in (("fd2", (12, 24, 48)), ("fe4", (6, 12, 24))):
        errors[scheme] = []
        for n in sizes:
            sol = softspine.solve(ROUTED, n_elements=n, scheme=scheme, residual_tol=1e-13)
            assert sol.converged and sol.stable, sol.message
            errors[scheme].append(np.abs(sol.positions - reference[:: 48 // n]).max() / 0.9)
    assert all(1.8 < p < 2.2 for p in observed_orders(errors["fd2"])), errors
    assert all(3.6 < p < 4.4 for p in observed_orders(errors["fe4"])), errors
    assert errors["fe4"][-1] < 2e-7, errors
    # The routing matters: the first routing all the way is elsewhere.
    first = [{**t, "offset": t["offset"][0], "twist": 0.0} for t in ROUTED["tendons"]]
    other = softspine.solve({**ROUTED, "tendons": first}, n_elements=48)
    assert np.abs(other.positions[-1] - reference[-1]).max() > 1e-3


def test_shooting_models_tendons_routed_section_by_section_at_fourth_order():
    # A change of routing starts at a section's start: an element ending
    # there is integrated with its own routing to its end. Against fe4 at
    # n = 480 (about 1e-12 off; fe4 against the Rucker-Webster rod: the slow
    # test above).
    reference = softspine.solve(ROUTED, scheme="fe4", n_elements=480, residual_tol=1e-13)
    errs = []
    for n in (12, 24, 48, 96):
        sol = softspine.solve(ROUTED, n_elements=n, method="shooting")
        assert sol.converged and sol.stable, sol.message
        errs.append(np.abs(sol.positions - reference.positions[:: 480 // n]).max() / 0.9)
    assert all(3.6 < p < 4.4 for p in observed_orders(errs)), errs
    assert errs[-1] < 1e-8, errs


def test_routings_round_trip_and_must_cover_the_sections_a_tendon_runs_through():
    data = softspine.Scene(ROUTED).to_dict()
    assert data["tendons"][1]["offset"] == [[-0.01, 0.002], [0.006, -0.01]]
    assert data["tendons"][1]["twist"] == [2.0, 2.0]
    assert softspine.Scene(data).to_dict() == data
    solver = softspine.Solver(ROUTED, n_elements=12, residual_tol=1e-13)
    solver.solve(check=True)
    sens = solver.sensitivity(["tendons[1].tension"])
    h = 1e-4
    tips = []
    for sign in (1, -1):
        moved = softspine.Scene(ROUTED).to_dict()
        moved["tendons"][1]["tension"] += sign * h
        tips.append(softspine.solve(moved, n_elements=12, residual_tol=1e-13).tip_position)
    np.testing.assert_allclose(sens.tip_position[:, 0], (tips[0] - tips[1]) / (2 * h), atol=1e-7)
    two = {**ROUTED["tendons"][0], "offset": ROUTED["tendons"][0]["offset"][:2], "twist": 0.0}
    with pytest.raises(ValueError, match=r"tendons\[0\].offset: 2 routings, .* through 3 sections"):
        softspine.solve({**ROUTED, "tendons": [two]})
    with pytest.raises(ValueError, match=r"tendons\[0\].twist: 2 entries, but offset gives 3"):
        softspine.solve({**ROUTED, "tendons": [{**ROUTED["tendons"][0], "twist": [1, 2]}]})
    with pytest.raises(ValueError, match=r"tendons\[0\].offset\[1\]"):
        bad = [[0.01, 0.0], [0.0, float("nan")], [0.0, 0.01]]
        softspine.solve({**ROUTED, "tendons": [{"tension": 1.0, "offset": bad}]})


MAGNETIC = {
    "length": L,
    "stiffness": {"kx": 0.05, "ky": 0.06, "kz": 0.04},
    "gravity": {"linear_density": 0.005, "vector": [0, 0, -9.81]},
    "magnetization": [[0.0, 0.0, 0.8], [0.3, 0.0, 0.5]],  # A m^2 / m, per section
    "tip_magnet": [0.0, 0.02, 0.05],  # A m^2
    "magnetic_field": [0.05, 0.02, 0.0],  # T
}


@pytest.mark.slow
def test_a_magnetised_rod_converges_to_the_shooting_reference_at_the_schemes_orders():
    reference = solve_reference(MAGNETIC, list(np.linspace(0, L, 33)), rtol=1e-10)

    def errors_of(scheme, sizes):
        out = []
        for n in sizes:
            how = {"method": "shooting"} if scheme == "rk4" else {"scheme": scheme}
            sol = softspine.solve(MAGNETIC, n_elements=n, residual_tol=1e-13, **how)
            assert sol.converged and sol.stable, sol.message
            out.append(np.abs(sol.positions - reference[:: 32 // n]).max() / L)
        return out

    fd2 = errors_of("fd2", [8, 16, 32])
    fe4 = errors_of("fe4", [4, 8, 16])
    assert all(1.8 < p < 2.2 for p in observed_orders(fd2)), fd2
    assert all(3.6 < p < 4.4 for p in observed_orders(fe4)), fe4
    assert fe4[-1] < 1e-7, fe4
    # Shooting (RK4) carries the moments (R mu) x B along the rod and at the
    # tip, turning with it (refused before).
    rk4 = errors_of("rk4", [4, 8, 16])
    assert all(3.6 < p < 4.4 for p in observed_orders(rk4)), rk4
    assert rk4[-1] < 1e-7, rk4


def test_a_field_sensitivity_and_the_magnetic_keys_round_trip():
    data = softspine.Scene(MAGNETIC).to_dict()
    assert data["magnetic_field"] == MAGNETIC["magnetic_field"]
    assert data["magnetization"] == MAGNETIC["magnetization"]
    solver = softspine.Solver(MAGNETIC, n_elements=16, residual_tol=1e-13)
    solver.solve(check=True)
    sens = solver.sensitivity("magnetic_field[1]")
    h = 1e-5
    tips = []
    for sign in (1, -1):
        changed = dict(MAGNETIC, magnetic_field=[0.05, 0.02 + sign * h, 0.0])
        tips.append(softspine.solve(changed, n_elements=16, residual_tol=1e-13).tip_position)
    np.testing.assert_allclose(sens.tip_position[:, 0], (tips[0] - tips[1]) / (2 * h), atol=1e-6)


def test_bad_magnetic_input_is_refused_by_name():
    with pytest.raises(ValueError, match=r"magnetization\[1\]"):
        softspine.solve({**MAGNETIC, "magnetization": [[0, 0, 1], [0, 1]]})
    with pytest.raises(ValueError, match="magnetised sections"):
        softspine.solve({**MAGNETIC, "magnetization": [[0, 0, 1]] * 3}, n_elements=16)
    with pytest.raises(ValueError, match="magnetic_field"):
        softspine.solve({**MAGNETIC, "magnetic_field": [0, float("inf"), 0]})
    # The paper's system has no magnets (shooting has, since).
    with pytest.raises(ValueError, match="magnetic actuation"):
        softspine.solve(MAGNETIC, method="paper")


def test_an_anchor_at_a_sum_of_section_lengths_is_at_the_tip():
    """0.1 * 3 is 0.30000000000000004: still the tip of a 0.3 m rod (it was
    refused as beyond the rod), and a point load there too."""
    scene = {
        "length": 0.3,
        "stiffness": {"kx": 1, "ky": 1, "kz": 1},
        "tendons": [{"tension": 1.0, "offset": [0.01, 0], "end": 0.1 * 3}],
        "point_loads": [{"s": 0.1 * 3, "force": [0, 0.1, 0]}],
    }
    sol = softspine.solve(scene, n_elements=30)
    assert sol.converged
    assert softspine.Scene(scene).to_dict()["tendons"][0]["end"] == 0.3


def test_a_solver_takes_new_tensions_and_fields():
    solver = softspine.Solver(SCENE, n_elements=16)
    solver.solve(check=True)
    solver.set_tensions([3.0, 0.0, 1.0])
    moved = solver.solve(check=True)
    data = softspine.Scene(SCENE).to_dict()
    for t, tension in zip(data["tendons"], [3.0, 0.0, 1.0], strict=True):
        t["tension"] = tension
    np.testing.assert_allclose(
        moved.positions, softspine.solve(data, n_elements=16).positions, atol=1e-9
    )
    with pytest.raises(ValueError, match=r"tensions\[1\]: a tendon pulls"):
        solver.set_tensions([1.0, -2.0, 0.0])
    with pytest.raises(ValueError, match="expected 3"):
        solver.set_tensions([1.0])
    magnetic = softspine.Solver(MAGNETIC, n_elements=16)
    magnetic.solve(check=True)
    magnetic.set_magnetic_field([0.0, 0.05, 0.0])
    turned = magnetic.solve(check=True)
    fresh = softspine.solve({**MAGNETIC, "magnetic_field": [0.0, 0.05, 0.0]}, n_elements=16)
    np.testing.assert_allclose(turned.positions, fresh.positions, atol=1e-9)
