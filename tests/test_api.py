"""The Python API: scenes from dicts and files, the Solution's fields, warm starts,
methods, status reporting, and the analytic Jacobian against finite differences."""

from __future__ import annotations

import json

import numpy as np
import pytest

import softspine
from softspine import Scene, SolverError
from softspine.scenes import cantilever, demo_robot_scene

from closed_forms import quat_mul

SCENE_3D = {
    "name": "3D test scene",
    "length": 0.9,
    "stiffness": {"kx": 0.7, "ky": 1.1, "kz": 0.5},
    "rest_curvature": [[1.5, -0.5], [-1.0, 2.0], [0.3, 0.0]],
    "gravity": {"linear_density": 0.15, "vector": [0.0, 0.0, -9.81]},
    "distributed_force": [0.1, 0.0, 0.0],
    "tip_force": [0.2, -0.4, 0.1],
    "tip_moment": [0.05, 0.1, -0.02],
    "base_quaternion": [0.0, 1.0, 0.0, 0.0],
    "tip": {"type": "free"},
}




def exp_half(theta):
    a = np.linalg.norm(theta)
    if a == 0:
        return np.array([1.0, 0, 0, 0])
    return np.concatenate([[np.cos(a / 2)], np.sin(a / 2) * theta / a])


def test_solution_fields_and_shapes():
    sol = softspine.solve(SCENE_3D, n_elements=30)
    assert sol.converged and sol.status == "converged" and sol.stable
    assert sol.n_elements == 30
    assert sol.positions.shape == (31, 3)
    assert sol.quaternions.shape == (31, 4)
    assert sol.forces.shape == (31, 3)
    assert np.allclose(sol.positions[0], 0.0)
    assert np.allclose(sol.tip_position, sol.positions[-1])
    assert np.allclose(sol.tip_quaternion, sol.quaternions[-1])
    assert np.allclose(np.linalg.norm(sol.quaternions, axis=1), 1.0, atol=1e-14)
    assert sol.residual_norm < 1e-10 and sol.iterations > 0
    # Internal force: the tip force at the tip, plus the whole distributed load at the base.
    f = np.array([0.1, 0.0, -0.15 * 9.81])
    assert np.allclose(sol.forces[-1], SCENE_3D["tip_force"])
    assert np.allclose(sol.forces[0], np.array(SCENE_3D["tip_force"]) + 0.9 * f)
    # Inextensible: every element keeps its length to second order.
    seg = np.linalg.norm(np.diff(sol.positions, axis=0), axis=1)
    assert np.allclose(seg, 0.9 / 30, rtol=1e-2)
    assert "converged" in repr(sol)


def test_scene_sources_agree(tmp_path):
    json_path = tmp_path / "scene.json"
    json_path.write_text(json.dumps(SCENE_3D))
    toml_path = tmp_path / "scene.toml"
    toml_path.write_text(
        """
name = "3D test scene"
length = 0.9
stiffness = { kx = 0.7, ky = 1.1, kz = 0.5 }
rest_curvature = [[1.5, -0.5], [-1.0, 2.0], [0.3, 0.0]]
gravity = { linear_density = 0.15, vector = [0.0, 0.0, -9.81] }
distributed_force = [0.1, 0.0, 0.0]
tip_force = [0.2, -0.4, 0.1]
tip_moment = [0.05, 0.1, -0.02]
base_quaternion = [0.0, 1.0, 0.0, 0.0]
[tip]
type = "free"
"""
    )
    tips = [
        softspine.solve(source, n_elements=30).tip_position
        for source in (SCENE_3D, Scene(SCENE_3D), str(json_path), toml_path)
    ]
    for t in tips[1:]:
        assert np.array_equal(t, tips[0])
    # to_dict round-trips.
    again = Scene(Scene(SCENE_3D).to_dict())
    assert np.array_equal(softspine.solve(again, n_elements=30).tip_position, tips[0])


def test_round_rod_stiffness():
    scene = Scene({"length": 1, "stiffness": {"E": 2e11, "G": 8e10, "diameter": 0.002}})
    i = np.pi * 0.002**4 / 64
    assert scene.stiffness == pytest.approx((2e11 * i, 2e11 * i, 8e10 * 2 * i))


def test_warm_start_takes_fewer_iterations():
    scene = demo_robot_scene()
    cold = softspine.solve(scene, n_elements=40)
    d = scene.to_dict()
    d["tip_force"] = [0.0, 0.0, -0.3]
    neighbour = softspine.solve(d, n_elements=40)
    warm = softspine.solve(scene, n_elements=40, initial=neighbour)
    assert warm.converged and cold.converged
    assert warm.iterations < cold.iterations
    assert np.allclose(warm.tip_position, cold.tip_position, atol=1e-12)
    # An array of quaternions works as well as a Solution.
    again = softspine.solve(scene, n_elements=40, initial=neighbour.quaternions)
    assert np.array_equal(again.tip_position, warm.tip_position)


def test_newton_and_lm_agree():
    newton = softspine.solve(SCENE_3D, n_elements=30, method="newton")
    lm = softspine.solve(SCENE_3D, n_elements=30, method="lm")
    assert newton.converged and lm.converged
    assert np.allclose(newton.positions, lm.positions, atol=1e-9)


def test_straight_rod_is_solved_without_iterating():
    sol = softspine.solve({"length": 2.0, "stiffness": {"kx": 1, "ky": 1, "kz": 1}}, n_elements=10)
    assert sol.converged and sol.iterations == 0 and sol.stable
    assert np.allclose(sol.tip_position, [0, 0, 2.0])


def test_non_convergence_is_reported_and_raised_on_request():
    sol = softspine.solve(cantilever(10.0), n_elements=20, max_iterations=1)
    assert not sol.converged and sol.status == "iteration_limit"
    assert not sol.stable
    assert sol.residual_norm > 1e-10
    with pytest.raises(SolverError, match="did not converge"):
        softspine.solve(cantilever(10.0), n_elements=20, max_iterations=1, check=True)


def test_analytic_jacobian_matches_central_differences():
    n = 9
    rng = np.random.default_rng(7)
    base = np.array(SCENE_3D["base_quaternion"], dtype=float)
    q = np.empty((n + 1, 4))
    q[0] = base
    for j in range(1, n + 1):
        q[j] = quat_mul(q[j - 1], exp_half(rng.normal(scale=0.3, size=3)))
    jac = softspine._core.jacobian(SCENE_3D, q)
    h = 1e-6
    fd = np.empty_like(jac)
    for j in range(1, n + 1):
        for c in range(3):
            d = np.zeros(3)
            d[c] = h
            qp, qm = q.copy(), q.copy()
            qp[j] = quat_mul(q[j], exp_half(d))
            qm[j] = quat_mul(q[j], exp_half(-d))
            gp = softspine._core.residual(SCENE_3D, qp).ravel()
            gm = softspine._core.residual(SCENE_3D, qm).ravel()
            fd[:, 3 * (j - 1) + c] = (gp - gm) / (2 * h)
    assert np.abs(jac - fd).max() < 1e-7 * (1 + np.abs(fd).max())
    # Block-tridiagonal: nothing beyond the neighbours.
    for i in range(n):
        for k in range(n):
            if abs(i - k) > 1:
                assert not jac[3 * i : 3 * i + 3, 3 * k : 3 * k + 3].any()
