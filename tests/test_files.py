"""Scenes and robots written to files and read back (issue 29, item 4): a
``Scene`` or a ``Robot`` saved as JSON or TOML reads back as the same
object, every field of ``to_dict()`` equal; a SciPy ``Rotation`` is taken
wherever an orientation is."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import softspine

FULL_SCENE = {
    "name": "every kind of key",
    "length": 1.0,
    "stiffness": {"E": 200e9, "G": 77e9, "diameter": 0.003},
    "rest_curvature": [[2.0, 0.0], [0.0, 2.0]],
    "gravity": {"linear_density": 0.2, "vector": [0, 0, -9.81]},
    "tip_force": [0.0, 0.0, -0.29],
    "tip_moment": [0.0, 0.01, 0.0],
    "distributed_moment": [0.0, 0.0, 0.001],
    "point_loads": [{"s": 0.5, "force": [0, 0, -0.1], "moment": [0, 0.02, 0]}],
    "base_quaternion": [math.sqrt(0.5), 0.0, math.sqrt(0.5), 0.0],
    "base_position": [0.1, -0.2, 0.3],
    "tip": {"type": "pinned", "position": [0.7, 0.0, -0.4]},
}

CONTACT_SCENE = {
    "length": 1.0,
    "stiffness": {"kx": 1.0, "ky": 1.0, "kz": 0.7},
    "base_quaternion": [math.sqrt(0.5), 0.0, math.sqrt(0.5), 0.0],
    "gravity": {"linear_density": 0.5, "vector": [0.0, 0.0, -9.81]},
    "ports": [{"position": [0.2, 0.0, 0.0]}],
    "obstacles": [
        {"shape": "half_space", "point": [0, 0, -0.3], "normal": [0, 0, 1], "friction": 0.3},
        {"shape": "sphere", "centre": [0.5, 0.3, 0.0], "radius": 0.05},
        {"shape": "capsule", "a": [0.9, -1, -0.2], "b": [0.9, 1, -0.2], "radius": 0.01},
        {"shape": "cylinder", "a": [1.2, -1, 0], "b": [1.2, 1, 0], "radius": 0.02},
        {"shape": "box", "centre": [0.4, -0.5, 0], "half_extents": [0.1, 0.05, 0.02],
         "orientation": [0.9238795, 0.3826834, 0, 0]},
        {"shape": "lumen", "centreline": [[0, 0, 0], [0.5, 0, 0], [1.0, 0.1, 0]],
         "radius": [0.05, 0.06, 0.05]},
        {"shape": "mesh", "vertices": [[2, 0, 0], [3, 0, 0], [2, 1, 0], [2, 0, 1]],
         "triangles": [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]]},
    ],
    "radius": 0.002,
}

TENDON_ROBOT = {
    "length": 0.3, "sections": 2, "linear_density": 0.05, "disk_mass": 0.0,
    "stiffness": {"E": 60e9, "G": 23e9, "diameter": 0.001},
    "tendons": [{"offset": [0.01 * math.cos(a), 0.01 * math.sin(a)], "section": 2}
                for a in (0.0, 2.1, 4.2)],
}


def same(a, b, path="") -> None:
    """``a == b`` field by field, naming the first that differs."""
    if isinstance(a, dict):
        assert isinstance(b, dict) and set(a) == set(b), (path, set(a) ^ set(b))
        for k in a:
            same(a[k], b[k], f"{path}.{k}")
    elif isinstance(a, (list, tuple, np.ndarray)):
        assert len(a) == len(b), path
        for i, (x, y) in enumerate(zip(a, b, strict=True)):
            same(x, y, f"{path}[{i}]")
    else:
        assert a == b and type(a) is type(b), (path, a, b)


def robots() -> list[softspine.Robot]:
    pneumatic = softspine.Robot()
    tendon = softspine.Robot(TENDON_ROBOT)
    magnetic = softspine.Robot.from_file("examples/robots/magnetic_catheter.toml")
    inserted = softspine.Robot({"obstacles": CONTACT_SCENE["obstacles"][:2],
                                "insertion_range": [0.0, 0.2]})
    return [pneumatic, tendon, magnetic, inserted]


@pytest.mark.parametrize("suffix", [".json", ".toml"])
@pytest.mark.parametrize("data", [FULL_SCENE, CONTACT_SCENE], ids=["loads", "contact"])
def test_a_scene_saved_reads_back_the_same(tmp_path, suffix, data):
    scene = softspine.Scene(data)
    path = tmp_path / f"scene{suffix}"
    scene.save(path)
    same(scene.to_dict(), softspine.Scene.from_file(path).to_dict())
    text = scene.to_json() if suffix == ".json" else scene.to_toml()
    assert text == path.read_text(encoding="utf-8")
    read = softspine.Scene.from_json if suffix == ".json" else softspine.Scene.from_toml
    same(scene.to_dict(), read(text).to_dict())


@pytest.mark.parametrize("suffix", [".json", ".toml"])
@pytest.mark.parametrize("index", range(4), ids=["pneumatic", "tendon", "magnetic", "contact"])
def test_a_robot_saved_reads_back_the_same(tmp_path, suffix, index):
    robot = robots()[index]
    path = tmp_path / f"robot{suffix}"
    robot.save(path)
    same(robot.to_dict(), softspine.Robot.from_file(path).to_dict())


def test_a_saved_scene_solves_to_the_same_answer(tmp_path):
    scene = softspine.Scene(FULL_SCENE)
    scene.save(tmp_path / "scene.toml")
    a = softspine.solve(scene, n_elements=20)
    b = softspine.solve(tmp_path / "scene.toml", n_elements=20)
    assert a.converged
    np.testing.assert_array_equal(a.positions, b.positions)


def test_a_file_of_another_kind_is_refused_by_name(tmp_path):
    with pytest.raises(ValueError, match=r"path: expected a \.json or \.toml file"):
        softspine.Scene(FULL_SCENE).save(tmp_path / "scene.yaml")
    with pytest.raises(ValueError, match=r"path: expected a \.json or \.toml file"):
        softspine.Robot().save(tmp_path / "robot.txt")


def test_the_toml_reads_as_a_person_would_write_it():
    text = softspine.Robot().to_toml()
    assert "sections = 10\n" in text  # an integer, not 10.0
    assert "[stiffness]" in text


@pytest.mark.parametrize("key", ["base_quaternion", "tip"])
def test_a_scipy_rotation_is_an_orientation_in_a_scene(key):
    turn = Rotation.from_euler("zyx", [30, 50, -20], degrees=True)
    w_first = np.roll(turn.as_quat(), 1)  # SciPy's quaternion is scalar last
    base = {"length": 1.0, "stiffness": {"kx": 1.0, "ky": 1.0, "kz": 1.0}}
    if key == "tip":
        given = {**base, "tip": {"type": "clamped", "position": [0.3, 0.1, 0.8],
                                 "quaternion": turn}}
        listed = {**base, "tip": {"type": "clamped", "position": [0.3, 0.1, 0.8],
                                  "quaternion": w_first.tolist()}}
    else:
        given, listed = {**base, key: turn}, {**base, key: w_first.tolist()}
    same(softspine.Scene(given).to_dict(), softspine.Scene(listed).to_dict())


def test_a_scipy_rotation_is_an_orientation_of_a_robot_and_an_obstacle():
    turn = Rotation.from_euler("x", 45, degrees=True)
    box = {"shape": "box", "centre": [0.4, 0, 0], "half_extents": [0.1, 0.1, 0.1]}
    given = softspine.Robot({"base_quaternion": turn,
                             "obstacles": [{**box, "orientation": turn}]})
    q = np.roll(turn.as_quat(), 1).tolist()
    listed = softspine.Robot({"base_quaternion": q, "obstacles": [{**box, "orientation": q}]})
    same(given.to_dict(), listed.to_dict())


def test_a_stack_of_rotations_is_not_one_orientation():
    turns = Rotation.from_euler("x", [[10], [20]], degrees=True)
    with pytest.raises(ValueError, match="base_quaternion"):
        softspine.Scene({"length": 1.0, "stiffness": {"kx": 1.0, "ky": 1.0, "kz": 1.0},
                         "base_quaternion": turns})
