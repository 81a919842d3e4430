"""Hard cases: each checks the right equilibrium or a clear failure, never a
wrong answer marked converged."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.optimize import brentq
from scipy.special import ellipe, ellipk

import softspine
from softspine.scenes import cantilever, end_moment

from closed_forms import observed_orders
from validation import shooting

ROUND = {"kx": 1.0, "ky": 1.0, "kz": 1.0}
EULER_CLAMPED_FREE = math.pi**2 / 4  # P_cr L^2 / EI
# Buckling of a clamped column under its own weight: (rho g) L^3 / EI = 7.837.
SELF_WEIGHT_CRITICAL = 7.837


def assert_order_two(errors):
    orders = observed_orders(errors)
    assert np.all((orders > 1.9) & (orders < 2.1)), (orders, errors)


@pytest.mark.parametrize("turns", [1.0, 1.5])
def test_roll_up_by_an_end_moment(turns):
    """M = 2 pi EI/L closes the circle; 3 pi EI/L overlaps itself (no contact)."""
    k = 2 * math.pi * turns
    exact = np.array([(1 - math.cos(k)) / k, 0.0, math.sin(k) / k])
    errors = []
    for n in (40, 80, 160):
        sol = softspine.solve(end_moment(turns), n_elements=n, check=True)
        errors.append(np.linalg.norm(sol.tip_position - exact))
        # Every node on the circle of radius 1/k about (1/k, 0, 0).
        radius = np.linalg.norm(sol.positions - [1 / k, 0, 0], axis=1)
        assert np.ptp(radius) < 20 / n**2
    assert_order_two(errors)
    assert errors[-1] < 1e-3


@pytest.mark.parametrize("load", [0.9, 1.3])
def test_column_under_its_own_weight(load):
    """Upright column, rho g L^3 / EI = load x the critical 7.837."""
    w = load * SELF_WEIGHT_CRITICAL
    column = {
        "length": 1.0,
        "stiffness": ROUND,
        "gravity": {"linear_density": w / 9.81, "vector": [0.0, 0.0, -9.81]},
    }
    straight = softspine.solve(column, n_elements=40, check=True)
    assert np.allclose(straight.positions[:, :2], 0.0)
    # Below the critical load the straight column is stable, beyond it is not.
    assert straight.stable == (load < 1.0)
    # A small imperfection toward +x: beyond the critical load the column buckles
    # to that side (a large deflection), below it barely moves.
    imperfect = {**column, "rest_curvature": [[0.0, 0.01]]}
    bent = softspine.solve(imperfect, n_elements=40, check=True)
    assert bent.stable
    if load > 1.0:
        assert bent.tip_position[0] > 0.2
        # Shooting finds the unstable, barely bent equilibrium here (it knows no
        # stability), so the buckled shape is checked by its own convergence:
        # the differences between n = 20, 40, 80 and 160 fall as n^-2.
        tips = [softspine.solve(imperfect, n_elements=n, check=True).tip_position
                for n in (20, 40, 80, 160)]
        assert_order_two([np.linalg.norm(b - a) for a, b in zip(tips, tips[1:], strict=False)])
    else:
        assert 0 < bent.tip_position[0] < 0.05


@pytest.mark.parametrize("factor", [0.95, 1.05])
def test_compressive_tip_force_around_the_euler_load(factor):
    p = factor * EULER_CLAMPED_FREE
    column = {"length": 1.0, "stiffness": ROUND, "tip_force": [0.0, 0.0, -p]}
    sol = softspine.solve(column, n_elements=40, check=True)
    assert np.allclose(sol.tip_position, [0, 0, 1])
    assert sol.stable == (factor < 1.0)
    imperfect = {**column, "tip_force": [1e-4, 0.0, -p]}
    bent = softspine.solve(imperfect, n_elements=80, check=True)
    assert bent.stable
    # Past the Euler load the same tiny side force gives a large deflection.
    assert (bent.tip_position[0] > 0.1) == (factor > 1.0)
    if factor > 1.0:
        # The buckled elastica in closed form: P / P_cr = (2 K(k) / pi)^2, tip
        # deflection 2 k / K(k), height 2 E(k) / K(k) - 1 (k = sin of half the tip angle).
        k = brentq(lambda k: (2 * ellipk(k**2) / math.pi) ** 2 - factor, 1e-9, 0.99)
        exact = np.array([2 * k / ellipk(k**2), 0.0, 2 * ellipe(k**2) / ellipk(k**2) - 1])
        assert np.linalg.norm(bent.tip_position - exact) < 1e-3
    else:
        exact = shooting.solve(imperfect, rtol=1e-12)["tip_position"]
        assert np.linalg.norm(bent.tip_position - exact) < 1e-6


def spiral_scene():
    """Rest turning 8 rad (more than 2 pi) in 3D, under gravity."""
    return {
        "length": 1.0,
        "stiffness": {"kx": 1.0, "ky": 1.0, "kz": 0.7},
        "rest_curvature": [[8.0 * math.cos(0.5 * k), 8.0 * math.sin(0.5 * k)] for k in range(10)],
        "gravity": {"linear_density": 0.1, "vector": [0.0, 0.0, -9.81]},
    }


SHOOTING_CASES = {
    "3D spiral, rest turning 8 rad, gravity": (spiral_scene(), (20, 40, 80)),
    "anisotropic kx = 10 ky, twist coupling": (
        {
            "length": 1.0,
            "stiffness": {"kx": 10.0, "ky": 1.0, "kz": 0.8},
            "rest_curvature": [[1.0, 1.0]],
            "tip_force": [0.5, 1.5, 0.3],
            "tip_moment": [0.2, 0.0, 0.3],
        },
        (20, 40, 80),
    ),
    "torsion 1000 times stiffer than bending": (
        {
            "length": 1.0,
            "stiffness": {"kx": 1.0, "ky": 2.0, "kz": 1000.0},
            "rest_curvature": [[2.0, -1.0], [0.0, 3.0]],
            "tip_force": [1.0, -0.5, 0.2],
        },
        (20, 40, 80),
    ),
    "very soft, alpha = 50": (cantilever(50.0), (40, 80, 160)),
}


@pytest.mark.slow
@pytest.mark.parametrize("name", list(SHOOTING_CASES))
def test_hard_scene_against_shooting(name):
    scene, ns = SHOOTING_CASES[name]
    exact = shooting.solve(scene, rtol=1e-12)["tip_position"]
    errors = []
    for n in ns:
        sol = softspine.solve(scene, n_elements=n, check=True)
        assert sol.stable, sol.message
        errors.append(np.linalg.norm(sol.tip_position - exact))
    assert_order_two(errors)
    assert errors[-1] < 1e-3 * scene["length"]


def test_very_stiff_rod_follows_linear_beam_theory():
    """alpha = 1e-4: deflection P L^3 / 3 EI, shortening of second order."""
    sol = softspine.solve(cantilever(1e-4), n_elements=20, check=True)
    assert sol.tip_position[0] == pytest.approx(1e-4 / 3, rel=1e-3)
    assert 1.0 - sol.tip_position[2] < 1e-8


def test_pinned_near_full_reach_and_beyond():
    base = {"length": 1.0, "stiffness": ROUND,
            "gravity": {"linear_density": 0.1, "vector": [0, 0, -9.81]}}
    direction = np.array([math.sin(0.3), 0.0, math.cos(0.3)])
    near = {**base, "tip": {"type": "pinned", "position": (0.999 * direction).tolist()}}
    sol = softspine.solve(near, n_elements=40)
    if sol.converged:
        # The right reaction: applying it as a tip force to the free rod puts the
        # tip where it was pinned.
        free = softspine.solve({**base, "tip_force": sol.tip_reaction_force.tolist()},
                               n_elements=40, initial=sol)
        assert free.converged
        assert np.linalg.norm(free.tip_position - 0.999 * direction) < 1e-8
        # A strongly strained rod: the reaction pulls along the chord.
        assert sol.tip_reaction_force @ direction > 10.0
    else:
        assert sol.message
    beyond = {**base, "tip": {"type": "pinned", "position": (1.001 * direction).tolist()}}
    with pytest.raises(ValueError, match="unreachable"):
        softspine.solve(beyond, n_elements=40)


@pytest.mark.parametrize("n", [2000, 5000])
def test_fine_discretisations_stay_accurate(n):
    sol = softspine.solve(cantilever(3.0), n_elements=n, check=True)
    exact = np.array([0.60325344, 0.0, 1 - 0.25442018])
    # Second order: 1.9e-4 at n = 20 becomes ~2e-8 at n = 2000 (BD's 8 digits limit).
    assert np.linalg.norm(sol.tip_position - exact) < 2e-4 * (20 / n) ** 2 + 2e-8


def to_mm_g(scene):
    """The same scene in millimetres, grams and seconds."""
    force, length, moment = 1e6, 1e3, 1e9  # N -> g mm/s^2, m -> mm, N m -> g mm^2/s^2
    out = {"length": scene["length"] * length,
           "stiffness": {k: v * force * length**2 for k, v in scene["stiffness"].items()}}
    if "rest_curvature" in scene:
        out["rest_curvature"] = (np.array(scene["rest_curvature"]) / length).tolist()
    if "gravity" in scene:
        out["gravity"] = {"linear_density": scene["gravity"]["linear_density"],
                          "vector": (np.array(scene["gravity"]["vector"]) * length).tolist()}
    for key, scale in (("tip_force", force), ("tip_moment", moment)):
        if key in scene:
            out[key] = (np.array(scene[key]) * scale).tolist()
    return out


def test_units_do_not_change_the_answer():
    scene = {"length": 0.8, "stiffness": {"kx": 0.6, "ky": 1.4, "kz": 0.5},
             "rest_curvature": [[2.0, -1.0], [-1.5, 2.5]],
             "gravity": {"linear_density": 0.1, "vector": [0.0, 0.0, -9.81]},
             "tip_force": [0.8, -0.5, 0.3], "tip_moment": [0.05, 0.02, -0.1]}
    si = softspine.solve(scene, n_elements=40, check=True)
    mm = softspine.solve(to_mm_g(scene), n_elements=40, check=True)
    assert np.allclose(mm.positions / 1e3, si.positions, atol=1e-12)
    # Stiffness of 1e-6 and 1e3 N m^2 with the loads scaled alike: the same shape.
    for scale in (1e-6, 1e3):
        scaled = {**scene,
                  "stiffness": {k: v * scale for k, v in scene["stiffness"].items()},
                  "gravity": {"linear_density": 0.1 * scale, "vector": [0.0, 0.0, -9.81]},
                  "tip_force": (np.array(scene["tip_force"]) * scale).tolist(),
                  "tip_moment": (np.array(scene["tip_moment"]) * scale).tolist()}
        sol = softspine.solve(scaled, n_elements=40, check=True)
        assert np.allclose(sol.positions, si.positions, atol=1e-12)


def test_levenberg_marquardt_reports_converged_only_when_certified():
    # At the iteration limit LM took a residual within tolerance for
    # convergence: the Newton step from 11 of 600 such answers (random
    # scenes, n = 20) was 1e-10 to 4e-10 rad, above residual_tol (3e30b16).
    from softspine._core import jacobian, residual

    rng = np.random.default_rng(5)
    checked = 0
    for _ in range(200):
        k = rng.uniform(0.5, 2)
        scene = {"length": 1.0, "stiffness": {"kx": k, "ky": k * rng.uniform(0.5, 2),
                                               "kz": k * 0.7},
                 "tip_force": list(rng.normal(size=3) * 15),
                 "tip_moment": list(rng.normal(size=3) * 3),
                 "rest_curvature": [list(rng.normal(size=2) * 3)]}
        sol = softspine.solve(scene, method="lm", n_elements=20)
        if not sol.converged:
            continue
        checked += 1
        g = residual(scene, sol.quaternions).ravel()
        step = np.linalg.solve(jacobian(scene, sol.quaternions), -g)
        assert np.abs(step).max() <= 1e-10, (scene, sol.iterations, np.abs(step).max())
    assert checked > 150
