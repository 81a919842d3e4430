"""Bad input: a ValueError that names the field and the reason, never a panic."""

from __future__ import annotations

import math

import numpy as np
import pytest

import softspine
from softspine import Scene

GOOD = {"length": 1.0, "stiffness": {"kx": 1.0, "ky": 1.0, "kz": 1.0}}


def with_(**changes):
    d = {**GOOD, **changes}
    return {k: v for k, v in d.items() if v is not None}


@pytest.mark.parametrize(
    "scene,key,reason",
    [
        (with_(length=-1.0), "length", "positive"),
        (with_(length=0.0), "length", "positive"),
        (with_(length=math.nan), "length", "finite"),
        (with_(length="1 m"), "length", "number"),
        (with_(length=None), "length", "missing"),
        (with_(stiffness={"kx": 1, "ky": -1, "kz": 1}), "stiffness.ky", "positive"),
        (with_(stiffness={"kx": 1, "ky": 1}), "stiffness.kz", "missing"),
        (with_(stiffness={"kx": 1, "ky": 1, "kz": 1, "E": 1}), "stiffness", "not both"),
        (with_(stiffness={"E": 2e11, "G": 8e10, "diameter": 0}), "stiffness.diameter", "positive"),
        (with_(stiffness={"kx": 1, "ky": 1, "kz": math.inf}), "stiffness.kz", "finite"),
        (with_(tip_force=[1.0, 2.0]), "tip_force", "3 numbers"),
        (with_(tip_force=[1.0, math.nan, 0.0]), "tip_force[1]", "finite"),
        (with_(tip_moment=[0.0, 0.0, -math.inf]), "tip_moment[2]", "finite"),
        (with_(distributed_force="down"), "distributed_force", "list"),
        (
            with_(gravity={"linear_density": -0.1, "vector": [0, 0, -9.81]}),
            "gravity.linear_density",
            "negative",
        ),
        (with_(gravity={"linear_density": 0.1}), "gravity.vector", "missing"),
        (with_(rest_curvature=[[1.0, 0.0], [1.0]]), "rest_curvature[1]", "2 numbers"),
        (with_(rest_curvature=[]), "rest_curvature", "at least one"),
        (with_(base_quaternion=[1.0, 1.0, 0.0, 0.0]), "base_quaternion", "unit"),
        (with_(tip={"type": "glued"}), "tip.type", "unknown tip type"),
        (with_(tip={"type": "free", "position": [0, 0, 1]}), "tip.position", "unknown key"),
        (with_(colour="red"), "colour", "unknown key"),
    ],
)
def test_invalid_scene_names_the_key(scene, key, reason):
    with pytest.raises(ValueError) as info:
        Scene(scene)
    message = str(info.value)
    assert message.startswith(f"{key}:"), message
    assert reason in message, message
    with pytest.raises(ValueError):
        softspine.solve(scene)


def test_numpy_values_are_accepted():
    d = with_(tip_force=np.array([0.5, 0.0, 0.0]), length=np.float64(1.0))
    assert softspine.solve(d).converged


@pytest.mark.parametrize(
    "kwargs,name",
    [
        ({"n_elements": 0}, "n_elements"),
        ({"n_elements": -4}, "n_elements"),
        ({"method": "magic"}, "method"),
        ({"tol": -1.0}, "tol"),
        ({"tol": math.nan}, "tol"),
        ({"max_iterations": 0}, "max_iterations"),
        ({"initial": np.ones((5, 4))}, "initial"),
        ({"initial": np.ones((21, 3))}, "initial"),
        ({"initial": np.full((21, 4), np.nan)}, "initial"),
    ],
)
def test_invalid_arguments_name_the_argument(kwargs, name):
    with pytest.raises(ValueError, match=f"^{name}:"):
        softspine.solve(GOOD, **kwargs)


def test_elements_must_fit_the_sections():
    scene = with_(rest_curvature=[[1, 0], [0, 1], [1, 1]])
    expected = "n_elements: must be a positive multiple of the number of sections \\(3\\)"
    with pytest.raises(ValueError, match=expected):
        softspine.solve(scene, n_elements=20)
    assert softspine.solve(scene, n_elements=21).converged


def test_files(tmp_path):
    bad = tmp_path / "scene.yaml"
    bad.write_text("length: 1")
    with pytest.raises(ValueError, match="json or .toml"):
        softspine.solve(str(bad))
    broken = tmp_path / "scene.json"
    broken.write_text("{length: 1")
    with pytest.raises(ValueError, match="invalid JSON"):
        softspine.solve(broken)
    with pytest.raises(ValueError, match="scene: expected"):
        softspine.solve(42)
