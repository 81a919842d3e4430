"""The Rust solver against two independent references: the NumPy implementation
of the same discrete model (agreement to 1e-10) and a tight-tolerance shooting
solution of the continuous Kirchhoff rod (second-order convergence)."""

from __future__ import annotations

import numpy as np
import pytest

import softspine

from closed_forms import observed_orders
from validation import reference, shooting


def random_unit_quaternion(rng):
    q = rng.normal(size=4)
    return q / np.linalg.norm(q)


def random_scene(seed):
    """A random moderate 3D scene: every term of the model is switched on."""
    rng = np.random.default_rng(seed)
    length = rng.uniform(0.5, 1.5)
    k = rng.uniform(0.5, 2.0, size=3)
    sections = int(rng.integers(1, 4))
    ei = k[:2].min()
    return {
        "length": length,
        "stiffness": {"kx": k[0], "ky": k[1], "kz": k[2]},
        "rest_curvature": rng.uniform(-2.0, 2.0, size=(sections, 2)).tolist(),
        "gravity": {"linear_density": rng.uniform(0.0, 0.5), "vector": [0.0, 0.0, -9.81]},
        "distributed_force": (rng.normal(size=3) * 0.5 * ei / length**2).tolist(),
        "tip_force": (rng.normal(size=3) * ei / length**2).tolist(),
        "tip_moment": (rng.normal(size=3) * 0.5 * ei / length).tolist(),
        "base_quaternion": random_unit_quaternion(rng).tolist(),
    }


def same_rotations(q1, q2):
    """Largest difference of quaternions taken up to sign."""
    sign = np.sign(np.sum(q1 * q2, axis=1))[:, None]
    return np.abs(q1 - sign * q2).max()


@pytest.mark.parametrize("seed", range(6))
def test_rust_and_numpy_reference_agree(seed):
    scene = random_scene(seed)
    sections = len(scene["rest_curvature"])
    n = 6 * sections
    rust = softspine.solve(scene, n_elements=n, residual_tol=1e-12, check=True)
    ref = reference.solve(scene, n_elements=n, tol=1e-13)
    length = scene["length"]
    assert np.abs(rust.positions - ref["positions"]).max() < 1e-10 * length
    assert same_rotations(rust.quaternions, ref["quaternions"]) < 1e-10
    assert rust.energy == pytest.approx(ref["energy"], rel=1e-10, abs=1e-12)
    assert np.allclose(rust.forces, reference.forces(scene, n), atol=1e-12)


@pytest.mark.parametrize("seed", range(4))
def test_residual_and_positions_agree_away_from_equilibrium(seed):
    scene = random_scene(100 + seed)
    rng = np.random.default_rng(seed)
    n = 3 * len(scene["rest_curvature"])
    q = np.array([random_unit_quaternion(rng) for _ in range(n + 1)])
    # Keep neighbours in one hemisphere, as along any continuous path.
    for j in range(1, n + 1):
        if q[j] @ q[j - 1] < 0:
            q[j] = -q[j]
    q[0] = scene["base_quaternion"]
    rust = softspine._core.residual(scene, q).ravel()
    ref = reference.residual(scene, q)
    assert np.abs(rust - ref).max() < 1e-12 * (1 + np.abs(ref).max())
    # The position formula, on a solved state.
    sol = softspine.solve(scene, n_elements=n)
    assert np.abs(reference.positions(scene, sol.quaternions) - sol.positions).max() < 1e-13


SCENES_3D = {
    "hanging robot, 10 sections, gravity and 30 g": {
        "length": 1.0,
        "stiffness": {"E": 200e9, "G": 77e9, "diameter": 0.003},
        "rest_curvature": [[3 * np.cos(0.6 * k), 3 * np.sin(0.6 * k)] for k in range(10)],
        "gravity": {"linear_density": 0.2, "vector": [0.0, 0.0, -9.81]},
        "tip_force": [0.0, 0.0, -0.2943],
        "base_quaternion": [0.0, 1.0, 0.0, 0.0],
    },
    "oblique tip force and moment, anisotropic, rotated base": {
        "length": 0.8,
        "stiffness": {"kx": 0.6, "ky": 1.4, "kz": 0.5},
        "rest_curvature": [[2.0, -1.0], [-1.5, 2.5]],
        "gravity": {"linear_density": 0.1, "vector": [0.0, 0.0, -9.81]},
        "tip_force": [0.8, -0.5, 0.3],
        "tip_moment": [0.1, 0.2, -0.15],
        "base_quaternion": [0.8660254037844387, 0.0, 0.5, 0.0],
    },
    "upright rod, sideways wind and gravity, 4 sections": {
        "length": 1.2,
        "stiffness": {"kx": 1.0, "ky": 1.0, "kz": 0.8},
        "rest_curvature": [[0.0, 2.0], [1.0, 1.0], [-2.0, 0.0], [0.5, -1.5]],
        "gravity": {"linear_density": 0.15, "vector": [0.0, 0.0, -9.81]},
        "distributed_force": [0.6, 0.3, 0.0],
        "tip_force": [0.0, 0.5, -0.2],
    },
}


@pytest.mark.parametrize("name", list(SCENES_3D))
def test_second_order_convergence_to_the_kirchhoff_rod(name):
    scene = SCENES_3D[name]
    exact = shooting.solve(scene, rtol=1e-12)
    errors = []
    for n in (20, 40, 80):
        sol = softspine.solve(scene, n_elements=n, check=True)
        assert sol.stable, sol.message
        errors.append(np.linalg.norm(sol.tip_position - exact["tip_position"]))
    orders = observed_orders(errors)
    assert np.all((orders > 1.9) & (orders < 2.1)), f"orders {orders}, errors {errors}"
    assert errors[-1] < 1e-3 * scene["length"], errors
    # The whole backbone, not only the tip: the nodes of n = 80 against shooting samples there.
    sol = softspine.solve(scene, n_elements=80)
    samples = shooting.solve(scene, rtol=1e-12, n_samples=81)["positions"]
    assert np.abs(sol.positions - samples).max() < 1e-3 * scene["length"]
