"""Pinned and clamped tips against a shooting solution of the continuous rod
with the same end conditions: positions and reactions converge at order 2."""

from __future__ import annotations

import numpy as np
import pytest

import softspine

from closed_forms import observed_orders, quat_mul
from validation import shooting, shooting_held

ROD = {
    "length": 0.9,
    "stiffness": {"kx": 0.8, "ky": 1.1, "kz": 0.6},
    "rest_curvature": [[1.5, -0.5], [-1.0, 2.0]],
    "gravity": {"linear_density": 0.12, "vector": [0.0, 0.0, -9.81]},
    "base_quaternion": [0.0, 1.0, 0.0, 0.0],
}




def held_scenes():
    free = shooting.solve(ROD)
    axis = np.array([0.3, -0.5, 0.8]) / np.linalg.norm([0.3, -0.5, 0.8])
    turn = np.concatenate([[np.cos(0.1)], np.sin(0.1) * axis])
    moved = (free["tip_position"] + [0.03, -0.02, 0.02]).tolist()
    return {
        "pinned": {**ROD, "tip_moment": [0.02, 0.0, -0.01],
                   "tip": {"type": "pinned", "position": [0.25, -0.1, -0.75]}},
        "clamped": {**ROD, "tip": {"type": "clamped", "position": moved,
                                   "quaternion": quat_mul(free["tip_quaternion"], turn).tolist()}},
    }


@pytest.mark.parametrize("kind", ["pinned", "clamped"])
def test_held_tip_converges_to_the_continuous_rod(kind):
    scene = held_scenes()[kind]
    exact = shooting_held.solve(scene, n_samples=81)
    force_errors, moment_errors = [], []
    for n in (20, 40, 80):
        sol = softspine.solve(scene, n_elements=n, check=True)
        assert sol.stable
        force_errors.append(np.linalg.norm(sol.tip_reaction_force - exact["tip_reaction_force"]))
        if kind == "clamped":
            moment_errors.append(
                np.linalg.norm(sol.tip_reaction_moment - exact["tip_reaction_moment"])
            )
    for errors in (force_errors, moment_errors):
        if errors:
            orders = observed_orders(errors)
            assert np.all((orders > 1.9) & (orders < 2.1)), (orders, errors)
    # The whole backbone at n = 80 against the shooting samples at its nodes.
    assert np.abs(sol.positions - exact["positions"]).max() < 1e-3 * scene["length"]
