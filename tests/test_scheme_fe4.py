"""scheme="fe4" (quadratic elements of the rotation, two-point Gauss
quadrature): fourth order on the whole backbone against the SciPy shooting
references of the continuous rod (free, pinned and clamped tips, guides)."""

from __future__ import annotations

import numpy as np
import pytest
from test_held_references import ROD, held_scenes
from test_shooting_method import FREE_3D

import softspine

from closed_forms import observed_orders, quat_mul
from validation import shooting, shooting_held

ROBOT_LIKE = {
    "length": 1.0,
    "stiffness": {"kx": 1.0, "ky": 1.25, "kz": 0.8},
    "rest_curvature": [[3, -1], [-2, 2.5], [0.5, -4], [4, 0], [-1.5, -3],
                       [2, 3], [-3.5, 1], [0, -2], [2.5, 2.5], [-4, 0.5]],
    "gravity": {"linear_density": 0.2, "vector": [3.0, -4.0, -9.81]},
    "tip_force": [0.5, 1.0, -0.3],
    "base_quaternion": [0.0, 1.0, 0.0, 0.0],
}
CANTILEVER = {"length": 1.0, "stiffness": {"kx": 1, "ky": 1, "kz": 1 / 1.3},
              "tip_force": [10.0, 0.0, 0.0]}


@pytest.mark.parametrize(("scene", "elements"), [
    (CANTILEVER, (10, 20, 40)),
    (FREE_3D, (10, 20, 40)),
    (ROBOT_LIKE, (10, 20, 40)),
])
def test_whole_backbone_converges_at_order_four(scene, elements):
    finest = 4 * elements[-1]
    exact = shooting.solve(scene, rtol=1e-13, n_samples=finest + 1)
    errors, rotations = [], []
    for n in elements:
        sol = softspine.solve(scene, n_elements=n, scheme="fe4", check=True)
        assert sol.stable
        nodes = slice(None, None, finest // n)
        errors.append(np.abs(sol.positions - exact["positions"][nodes]).max())
        # The angle between the frames, from the vector part (accurate near 0).
        conj = exact["quaternions"][nodes] * [1, -1, -1, -1]
        rel = np.array([quat_mul(c, q) for c, q in zip(conj, sol.quaternions, strict=True)])
        rotations.append(2 * np.arcsin(np.linalg.norm(rel[:, 1:], axis=1)).max())
    for e in (errors, rotations):
        orders = observed_orders(e)
        assert np.all((orders > 3.7) & (orders < 4.3)), (orders, e)
    # Far ahead of the second-order scheme at the same n.
    fd2 = softspine.solve(scene, n_elements=elements[-1], check=True)
    assert errors[-1] < 1e-3 * np.abs(fd2.positions - exact["positions"][nodes]).max()


def test_the_rest_shape_is_exact_in_the_scheme_without_iterating():
    scene = {k: v for k, v in ROBOT_LIKE.items() if k not in ("gravity", "tip_force")}
    sol = softspine.solve(scene, n_elements=10, scheme="fe4", check=True)
    assert sol.iterations == 0 and sol.residual_norm < 1e-12
    # Every section is an arc: the nodes lie on it to the scheme's order.
    exact = shooting.solve(scene, n_samples=11)
    assert np.abs(sol.positions - exact["positions"]).max() < 1e-5


@pytest.mark.parametrize("kind", ["pinned", "clamped"])
def test_held_tips_and_their_reactions_are_fourth_order(kind):
    """The reactions enter the internal nodes' balance, and the held points
    move with them through those nodes: the KKT system has a lower-right block."""
    scene = held_scenes()[kind]
    errors = {"positions": [], "force": [], "moment": []}
    for n in (20, 40, 80):
        exact = shooting_held.solve(scene, n_samples=n + 1)
        sol = softspine.solve(scene, n_elements=n, scheme="fe4", check=True)
        assert sol.stable and sol.scheme == "fe4"
        errors["positions"].append(np.abs(sol.positions - exact["positions"]).max())
        errors["force"].append(np.linalg.norm(sol.tip_reaction_force - exact["tip_reaction_force"]))
        if kind == "clamped":
            errors["moment"].append(
                np.linalg.norm(sol.tip_reaction_moment - exact["tip_reaction_moment"]))
    for name, e in errors.items():
        if e:
            orders = observed_orders(e)
            assert np.all((orders > 3.7) & (orders < 4.3)), (name, orders, e)


def test_a_guide_and_its_reaction_are_fourth_order():
    free = softspine.solve(ROD, n_elements=1280)
    guided = {**ROD, "tip_force": [0.1, 0.0, 0.0], "guides": [
        {"s": 0.45, "position": (free.positions[640] + [0.02, -0.01, 0.0]).tolist()}]}
    # The second-order scheme's Richardson limit from n = 640 and 1280.
    a = softspine.solve(guided, n_elements=640, scheme="fd2", check=True)
    b = softspine.solve(guided, n_elements=1280, scheme="fd2", check=True)
    positions = (4 * b.positions[::2] - a.positions) / 3
    reaction = (4 * b.guide_reactions - a.guide_reactions) / 3
    shape, force = [], []
    for n in (10, 20, 40):
        sol = softspine.solve(guided, n_elements=n, scheme="fe4", check=True)
        assert sol.stable
        shape.append(np.abs(sol.positions - positions[:: 640 // n]).max())
        force.append(np.linalg.norm(sol.guide_reactions - reaction))
    for e in (shape, force):
        orders = observed_orders(e)
        assert np.all((orders > 3.7) & (orders < 4.3)), (orders, e)


@pytest.mark.parametrize("method", ["paper", "shooting"])
def test_methods_with_their_own_discretisation_refuse_fe4(method):
    with pytest.raises(ValueError, match="scheme"):
        softspine.solve(CANTILEVER, method=method, scheme="fe4")


def test_scheme_is_a_setting():
    settings = softspine.Settings(scheme="fe4")
    assert settings.scheme == "fe4" and settings.to_dict()["scheme"] == "fe4"
    with pytest.raises(ValueError, match="scheme.*'fd4'"):
        softspine.Settings(scheme="fd4")
    a = softspine.solve(CANTILEVER, settings, n_elements=10)
    b = softspine.solve(CANTILEVER, n_elements=10, scheme="fe4")
    assert np.array_equal(a.positions, b.positions)
