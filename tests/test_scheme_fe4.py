"""scheme="fe4" (quadratic elements of the rotation, two-point Gauss
quadrature): fourth order on the whole backbone against the SciPy shooting
references of the continuous rod, and refused where it does not apply yet."""

from __future__ import annotations

import numpy as np
import pytest
from test_shooting_method import FREE_3D

import softspine

from closed_forms import observed_orders, quat_mul
from validation import shooting

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


@pytest.mark.parametrize("tip", [
    {"type": "pinned", "position": [0.3, 0.0, 0.9]},
    {"type": "clamped", "position": [0.3, 0.0, 0.9], "quaternion": [1, 0, 0, 0]},
])
def test_held_tips_are_refused_by_name_for_now(tip):
    with pytest.raises(ValueError, match="scheme.*fe4.*held"):
        softspine.solve({**CANTILEVER, "tip_force": [0, 0, 0], "tip": tip}, scheme="fe4")


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
