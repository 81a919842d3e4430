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
    sol = softspine.solve(curved_scene(3), tol=1e-4, method="newton", check=True)
    # Doubling from 21 (the rest shape is resolved at 21 already).
    assert sol.n_elements % 21 == 0 and ((sol.n_elements // 21) & (sol.n_elements // 21 - 1)) == 0
    assert sol.n_elements > 21 and sol.error_estimate <= 1e-4


# --- issue 11, item 2: orientations ------------------------------------------------------

BASE = {"length": 1.0, "stiffness": {"kx": 1.0, "ky": 1.3, "kz": 0.7}, "tip_force": [0.2, 0.1, 0.0]}


def scalar_first(rotation):
    x, y, z, w = rotation.as_quat()
    return [w, x, y, z]


def test_the_readmes_rounded_quaternion_is_accepted_and_normalised():
    """[0.924, 0, 0.383, 0] (norm 1.00023) was refused at a tolerance of 1e-6."""
    q = [0.924, 0.0, 0.383, 0.0]
    tip = {"type": "clamped", "position": [0.3, 0.0, 0.9], "quaternion": q}
    sol = softspine.solve({"length": 1.0, "stiffness": BASE["stiffness"], "tip": tip}, check=True)
    unit = np.asarray(q) / np.linalg.norm(q)
    assert np.abs(sol.tip_quaternion - unit).max() < 1e-12
    sol = softspine.solve(dict(BASE, base_quaternion=q), check=True)
    assert np.abs(sol.quaternions[0] - unit).max() < 1e-15


def test_a_scipy_rotation_matrix_is_the_same_orientation_as_its_quaternion():
    from scipy.spatial.transform import Rotation

    rotation = Rotation.from_rotvec([0.3, -1.2, 2.5])
    by_quaternion = softspine.solve(dict(BASE, base_quaternion=scalar_first(rotation)))
    by_matrix = softspine.solve(dict(BASE, base_quaternion=rotation.as_matrix()))
    by_list = softspine.solve(dict(BASE, base_quaternion=rotation.as_matrix().tolist()))
    for sol in (by_matrix, by_list):
        assert np.abs(sol.positions - by_quaternion.positions).max() < 1e-14
    # The base tangent is the matrix's third column (material z in the world).
    assert np.allclose(by_matrix.positions[1] / np.linalg.norm(by_matrix.positions[1]),
                       rotation.as_matrix()[:, 2], atol=0.05)
    # A clamped tip and a robot's base take a matrix too.
    tip = Rotation.from_rotvec([0.0, 0.8, 0.0])
    held = {"length": 1.0, "stiffness": BASE["stiffness"]}
    clamped = lambda o: dict(held, tip={"type": "clamped", "position": [0.3, 0, 0.9],  # noqa: E731
                                         "quaternion": o})
    a = softspine.solve(clamped(scalar_first(tip)), check=True)
    b = softspine.solve(clamped(tip.as_matrix()), check=True)
    assert np.abs(a.positions - b.positions).max() < 1e-14
    turned = Rotation.from_rotvec([np.pi, 0.0, 0.0])
    robots = [softspine.Robot({"base_quaternion": o})
              for o in (scalar_first(turned), turned.as_matrix())]
    kappa = [[0.5, 0.0]] * 10
    shapes = [r.forward(kappa).positions for r in robots]
    assert np.abs(shapes[0] - shapes[1]).max() < 1e-14


@pytest.mark.parametrize(
    "orientation, reason",
    [
        ([0.9, 0.0, 0.383, 0.0], "within 0.001 of norm 1"),
        ([[1, 0, 0], [0, 1, 0], [0, 0, -1]], "det R = -1"),
        ((1.01 * np.eye(3)).tolist(), "must be a rotation matrix"),
        ([[1, 0], [0, 1]], "a 3x3 rotation matrix or a scipy Rotation"),
        ([[1, 0, 0], [0, 1, 0], [0, 0, "x"]], r"base_quaternion\[2\]\[2\]"),
    ],
)
def test_a_bad_orientation_is_refused_naming_the_key(orientation, reason):
    with pytest.raises(ValueError, match=r"^base_quaternion") as info:
        softspine.solve(dict(BASE, base_quaternion=orientation))
    assert info.match(reason)
    with pytest.raises(ValueError, match=r"^base_quaternion"):
        softspine.Robot({"base_quaternion": orientation})


# --- issue 11, item 2: base_position -----------------------------------------------------


def test_a_base_position_translates_the_rod_and_its_held_points():
    from validation import reference

    offset = np.array([0.4, -1.5, 2.0])
    free = dict(BASE, rest_curvature=[[1.0, -0.5]],
                gravity={"linear_density": 0.2, "vector": [0.0, 0.0, -9.81]})
    at_origin = softspine.solve(free, check=True)
    moved = softspine.solve(dict(free, base_position=offset.tolist()), check=True)
    assert np.abs(moved.positions - (at_origin.positions + offset)).max() < 1e-14
    assert np.abs(moved.quaternions - at_origin.quaternions).max() < 1e-14
    # The NumPy reference places the nodes the same way.
    scene = dict(free, base_position=offset.tolist())
    assert np.abs(reference.positions(scene, moved.quaternions) - moved.positions).max() < 1e-14
    # A held target is in the same world frame: the same shape, the same reaction.
    target = (at_origin.tip_position * [0.9, 0.9, 0.95]).tolist()
    pinned = softspine.solve(dict(free, tip={"type": "pinned", "position": target}), check=True)
    shifted = dict(free, base_position=offset.tolist(),
                   tip={"type": "pinned", "position": (np.asarray(target) + offset).tolist()})
    pinned_moved = softspine.solve(shifted, check=True)
    assert np.abs(pinned_moved.positions - (pinned.positions + offset)).max() < 1e-12
    assert np.abs(pinned_moved.tip_reaction_force - pinned.tip_reaction_force).max() < 1e-10
    # Reach is measured from the base: the untranslated target is out of reach.
    with pytest.raises(ValueError, match=r"^tip.position: unreachable"):
        softspine.solve(dict(shifted, tip={"type": "pinned", "position": [0.0, 0.0, 0.5]}))
    # The scene round-trips with it.
    assert softspine.Scene(scene).to_dict()["base_position"] == offset.tolist()


def test_a_robot_with_a_base_position_reaches_translated_targets():
    offset = [0.1, 0.2, -0.3]
    robot = softspine.Robot({"sections": 3})
    moved = softspine.Robot({"sections": 3, "base_position": offset})
    kappa = [[1.0, 0.0], [0.0, -1.0], [0.5, 0.5]]
    a, b = robot.forward(kappa), moved.forward(kappa)
    assert np.abs(b.positions - (a.positions + offset)).max() < 1e-14
    ik = moved.inverse(b.tip_position)
    assert ik.reached and np.linalg.norm(ik.tip_position - b.tip_position) < 1e-6
    assert moved.to_dict()["base_position"] == offset
