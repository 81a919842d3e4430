"""Bad input: a ValueError that names the field and the reason, never a panic."""

from __future__ import annotations

import math
import re
import warnings

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
        # The shear modulus missing: how to get it, and the other way to give
        # the stiffness (issue 29, item 8).
        (with_(stiffness={"E": 2e6, "diameter": 0.01}), "stiffness.G",
         "missing: the shear modulus [Pa] of the round rod"),
        (with_(stiffness={"E": 2e6, "diameter": 0.01}), "stiffness.G",
         "or give the stiffnesses {kx, ky, kz} [N m^2] instead"),
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
        # A warm start brings its own n, but not against n_elements.
        ({"initial": np.ones((5, 4)), "n_elements": 20}, "initial"),
        ({"initial": np.ones((1, 4))}, "initial"),
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


# --- Units no rod can mean, and units merely suspicious ---------------------------

TENDON_ROD = {"length": 0.2425, "stiffness": {"E": 210e9, "G": 80e9, "diameter": 1.4e-3},
              "tendons": [{"tension": 5.0, "offset": [0.01, 0.0], "end": 0.2425}]}


@pytest.mark.parametrize(
    "changes,key,hint",
    [
        # 1.4 meant in millimetres: converged after 0 iterations, straight (3e30b16).
        ({"stiffness": {"E": 210e9, "G": 80e9, "diameter": 1.4}}, "stiffness.diameter",
         "millimetres meant"),
        ({"tendons": [{"tension": 5.0, "offset": [10.0, 0.0], "end": 0.2425}]},
         r"tendons\[0\].offset", "millimetres meant"),
        ({"stiffness": {"kx": 1e-9, "ky": 1e-9, "kz": 1e-9}, "tip_force": [1e5, 0.0, 0.0]},
         "tip_force", "check the units"),
    ],
)
def test_inputs_no_rod_can_mean_are_refused_with_the_likely_mistake(changes, key, hint):
    with pytest.raises(ValueError, match=f"^{key}: .*{hint}"):
        softspine.solve({**TENDON_ROD, **changes})


@pytest.mark.parametrize(
    "changes,key,hint",
    [
        # E = 210 meant in GPa: 500 iterations, then a failure naming nothing.
        ({"stiffness": {"E": 210.0, "G": 80e9, "diameter": 1.4e-3}}, "stiffness.E", "GPa"),
        ({"tendons": [{"tension": 0.5, "offset": [0.1, 0.0], "end": 0.2425}]},
         r"tendons\[0\].offset", "millimetres meant"),
        ({"stiffness": {"E": 1e6, "G": 3e5, "diameter": 0.05}}, "stiffness.diameter",
         "slender-rod model"),
        ({"stiffness": {"kx": 1e9, "ky": 1e9, "kz": 1e9}, "tendons": [],
          "tip_force": [1e-5, 0.0, 0.0]}, "tip_force", "less than round-off"),
    ],
)
def test_suspicious_units_warn_naming_the_key(changes, key, hint):
    with pytest.warns(UserWarning, match=f"^{key}.*{hint}"):
        softspine.Scene({**TENDON_ROD, **changes})


def test_a_payload_in_grams_given_as_kilograms_warns():
    robot = softspine.Robot()
    kappa = [[0.5, 0.0]] * robot.sections
    with pytest.warns(UserWarning, match="^load = 30 kg is 100 times the robot's own mass"):
        robot.forward(kappa, load=30)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        robot.forward(kappa, load=0.03)


def test_a_failed_solve_names_the_load_scale_it_reached():
    soft = {**TENDON_ROD, "stiffness": {"E": 210.0, "G": 80.0, "diameter": 1.4e-3}}
    with pytest.warns(UserWarning):
        sol = softspine.solve(soft)
    assert not sol.converged
    assert re.search(r"at load scale \d\.\d{3} of 1\).*kappa L = 4\.02e8", sol.message), sol.message


@pytest.mark.parametrize("call, message", [
    (lambda r, t: r.forward(tensions=[1.0, 2.0, 3.0]),
     "tensions: this robot has no tendons: it is driven by its pneumatic muscles"),
    (lambda r, t: r.forward(field=[0.0, 0.0, 0.01]),
     "field: this robot has no magnetised material: it is driven by its pneumatic muscles"),
    (lambda r, t: r.forward_batch(tensions=[[1.0, 2.0, 3.0]]),
     "tensions: this robot has no tendons"),
    (lambda r, t: t.forward(field=[0.0, 0.0, 0.01]),
     "field: this robot has no magnetised material: it is driven by its tendons"),
    (lambda r, t: t.forward(tensions=[1.0, 2.0, 3.0]),
     "tensions: expected 9 tensions, one a tendon, got 3"),
])
def test_a_drive_the_robot_lacks_is_refused_saying_what_drives_it(call, message):
    # Issue 29, item 8: "tensions: expected one a tendon (0), got 3" was
    # garbled, and a field on a robot without magnets moved nothing, silently.
    robot = softspine.Robot()
    tendons = softspine.Robot.from_file("examples/robots/tendon_robot.toml")
    with pytest.raises(ValueError, match=re.escape(message)):
        call(robot, tendons)
