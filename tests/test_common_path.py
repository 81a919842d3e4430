"""Issue 11, item 1: the common path works for any robot. The default number
of elements is one rule in the core: the smallest multiple of the sections that
is at least 20. Scenes of 3, 6, 7, 8, 9, 11 or 12 sections used to fail with
default settings (``n_elements: must be a positive multiple of the number of
sections (3), got 20``), and ``Robot({"sections": 3})`` used n = 6."""

from __future__ import annotations

import json

import numpy as np
import pytest

import softspine
from softspine.cli import main


def curved_scene(sections):
    """A rod of ``sections`` sections of alternating rest curvature, loaded."""
    return {
        "length": 1.0,
        "stiffness": {"kx": 1.0, "ky": 1.2, "kz": 0.8},
        "rest_curvature": [[0.8 * (-1) ** i, 0.3] for i in range(sections)],
        "gravity": {"linear_density": 0.1, "vector": [0.0, 0.0, -9.81]},
        "tip_force": [0.2, 0.0, 0.0],
    }


@pytest.mark.parametrize(
    "sections, n",
    [(1, 20), (3, 21), (4, 20), (6, 24), (7, 21), (8, 24), (9, 27), (11, 22), (12, 24), (25, 25)],
)
def test_any_number_of_sections_solves_with_the_default_n(sections, n):
    scene = curved_scene(sections)
    sol = softspine.solve(scene, check=True)
    assert sol.n_elements == n
    # The same as asking for that n.
    same = softspine.solve(scene, n_elements=n, check=True)
    assert np.array_equal(sol.positions, same.positions)


def test_a_scene_file_of_three_sections_solves_and_demos(tmp_path, capsys):
    path = tmp_path / "my_scene.json"
    path.write_text(json.dumps(curved_scene(3)))
    assert softspine.solve(str(path), check=True).n_elements == 21
    assert main(["demo", "--scene", str(path), "--out", str(tmp_path / "demo.png")]) == 0
    assert "n = 21" in capsys.readouterr().out


def test_a_robot_of_three_sections_uses_the_default_n():
    robot = softspine.Robot({"sections": 3})
    assert robot.n_elements == 21
    kappa = [[1.0, 0.0], [0.0, -1.0], [0.5, 0.5]]
    forward = robot.forward(kappa)
    assert forward.converged and forward.n_elements == 21
    # The robot's scene solves with the default n too, to the same shape.
    sol = softspine.solve(robot.scene(kappa), check=True)
    assert sol.n_elements == 21
    assert np.abs(sol.positions - forward.positions).max() < 1e-12


def test_accuracy_on_demand_starts_from_the_default_n():
    sol = softspine.solve(curved_scene(3), tol=1e-4, check=True)
    # Doubling from 21 (the rest shape is resolved at 21 already).
    assert sol.n_elements % 21 == 0 and ((sol.n_elements // 21) & (sol.n_elements // 21 - 1)) == 0
    assert sol.n_elements > 21 and sol.error_estimate <= 1e-4
