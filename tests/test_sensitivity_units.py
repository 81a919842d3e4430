"""Sensitivities do not depend on the units: the same rod in metres,
millimetres and kilometres gives the same derivatives (converted), and every
kind of parameter matches differences of whole solves in each unit system.

A parameter's step in the discrete equations' differences once came from its
own units (`1e-6 * max(|p|, 1e-3)`): on a rod in centimetres a tip force's
derivative lost every digit and came out zero."""

from __future__ import annotations

import copy
import re

import numpy as np
import pytest
from test_sensitivity import tip_pose

import softspine

TIGHT = 1e-13

# An SI rod with every effect the sensitivities reach: sections of their own
# length, stiffness and density, rest curvature, gravity, tip force and moment,
# a point load on the sections' joint, a helical tendon, a magnetised section.
BASE = {
    "length": 0.6,
    "stiffness": {"kx": 0.01, "ky": 0.01, "kz": 0.01},
    "sections": [
        {"length": 0.25, "stiffness": {"kx": 0.02, "ky": 0.03, "kz": 0.015},
         "linear_density": 0.05},
        {"length": 0.35, "stiffness": {"kx": 0.01, "ky": 0.012, "kz": 0.008},
         "linear_density": 0.03},
    ],
    "rest_curvature": [[0.8, -0.3], [0.2, 0.5]],
    "gravity": {"linear_density": 0.04, "vector": [0.0, 0.5, -9.81]},
    "tip_force": [0.02, -0.01, -0.03],
    "tip_moment": [0.002, 0.001, -0.003],
    "distributed_moment": [0.001, -0.002, 0.0005],
    "point_loads": [{"s": 0.25, "force": [0.01, 0.02, 0.0], "moment": [0.001, 0.0, -0.002]}],
    "tendons": [{"tension": 0.5, "offset": [0.01, 0.0], "twist": 0.3}],
    "magnetization": [[0.0, 0.0, 0.0], [0.0, 0.0, 0.5]],
    "magnetic_field": [0.01, 0.0, 0.02],
}

# The power of the unit of length in each field of a system of a length unit,
# the kilogram, the second and the ampere (millimetres: forces in kg mm / s^2 =
# 1e-3 N): a stiffness in N m^2, a density in kg/m, a field in T = kg / (A s^2),
# a magnetisation in A m^2 / m, a twist in rad/m.
LENGTH_POWER = [
    (r"(^|\.)length$", 1),
    (r"stiffness\.k[xyz]$", 3),
    (r"linear_density$", -1),
    (r"^gravity\.vector\[\d\]$", 1),
    (r"^tip_force\[\d\]$", 1),
    (r"^tip_moment\[\d\]$", 2),
    (r"^point_loads\[\d\]\.s$", 1),
    (r"^point_loads\[\d\]\.force\[\d\]$", 1),
    (r"^point_loads\[\d\]\.moment\[\d\]$", 2),
    (r"^distributed_moment\[\d\]$", 1),
    (r"^tendons\[\d\]\.tension$", 1),
    (r"^tendons\[\d\]\.offset\[\d\]$", 1),
    (r"^tendons\[\d\]\.twist$", -1),
    (r"^tendons\[\d\]\.end$", 1),
    (r"^magnetization\[\d\]\[\d\]$", 1),
    (r"^magnetic_field\[\d\]$", 0),
    (r"^rest_curvature\[\d\]\[\d\]$", -1),
    (r"^tip\.position\[\d\]$", 1),
]

PARAMETERS = [
    "tip_force[0]", "tip_force[2]", "tip_moment[1]", "sections[0].stiffness.kx",
    "sections[1].stiffness.kz", "sections[1].linear_density", "gravity.vector[1]",
    "rest_curvature[1][0]", "tendons[0].tension", "tendons[0].offset[0]", "tendons[0].twist",
    "magnetic_field[2]", "magnetization[1][2]", "point_loads[0].force[1]", "sections[0].length",
    "sections[1].length", "point_loads[0].moment[0]", "distributed_moment[1]",
]
# The parameters that move the mesh: their equations' derivative is
# differenced (central at one and two steps, extrapolated); every other one,
# a tendon's routing too, is the terms' own.
DIFFERENCED = {"sections[0].length", "sections[1].length"}


def power_of(path: str) -> int:
    for pattern, power in LENGTH_POWER:
        if re.search(pattern, path):
            return power
    raise KeyError(path)


def leaves(value, path=""):
    """Every numeric leaf of a scene's dict, by its path."""
    if isinstance(value, dict):
        for key, item in value.items():
            yield from leaves(item, f"{path}.{key}" if path else key)
    elif isinstance(value, list):
        for i, item in enumerate(value):
            yield from leaves(item, f"{path}[{i}]")
    elif isinstance(value, (int, float)) and not isinstance(value, bool):
        yield path


def at(data, path):
    """The container of a leaf and its key."""
    parts = re.findall(r"[^.\[\]]+", path)
    for part in parts[:-1]:
        data = data[int(part)] if isinstance(data, list) else data[part]
    last = parts[-1]
    return data, (int(last) if isinstance(data, list) else last)


def in_units(scene, metres):
    """The scene with lengths in a unit of `1 / metres` m (1e3: millimetres)."""
    out = copy.deepcopy(scene)
    for path in list(leaves(scene)):
        box, key = at(out, path)
        box[key] = float(box[key]) * metres ** power_of(path)
    return out


def moved(scene, path, delta):
    out = copy.deepcopy(scene)
    box, key = at(out, path)
    box[key] += delta
    if re.fullmatch(r"sections\[(\d)\]\.length", path):
        # The rod's length with its section's; on the sections' joint the
        # point load stays there only when the first section moves.
        out["length"] += delta
        if path == "sections[0].length":
            out["point_loads"][0]["s"] += delta
    return out


def test_the_issues_rod_gives_one_dimensionless_answer_in_three_unit_systems():
    answers = []
    for length, k in [(1.0, 1.0), (0.1, 1e3), (0.01, 1e5), (1e3, 1e-9)]:
        data = {"length": length, "stiffness": {"kx": k, "ky": k, "kz": 0.77 * k},
                "tip_force": [k / length**2, 0, 0]}
        solver = softspine.Solver(data)
        solver.solve(check=True)
        answers.append(solver.sensitivity(["tip_force[2]"]).tip_position[:, 0] * k / length**3)
    # A whole solve's difference (in the first system) gives -0.0963, 0, 0.0379.
    np.testing.assert_allclose(answers[0], [-0.0963, 0, 0.0379], atol=1e-4)
    for other in answers[1:]:
        np.testing.assert_allclose(other, answers[0], rtol=0, atol=1e-10)


@pytest.mark.parametrize("scheme", ["fd2", "fe4"])
def test_the_same_rod_in_any_units_has_the_same_sensitivities(scheme):
    n = 24 if scheme == "fd2" else 12
    columns = {}
    for metres in (1.0, 1e3, 1e-3):
        solver = softspine.Solver(in_units(BASE, metres), n_elements=n, scheme=scheme,
                                  residual_tol=TIGHT)
        solver.solve(check=True)
        sens = solver.sensitivity(PARAMETERS)
        assert [not e for e in sens.exact] == [p in DIFFERENCED for p in PARAMETERS]
        # Back to SI: d r / d p scales as metres^(1 - power), d phi / d p as
        # metres^(-power).
        powers = np.array([power_of(p) for p in PARAMETERS], dtype=float)
        columns[metres] = np.vstack([
            sens.tip_position * metres ** (powers - 1.0),
            sens.tip_rotation * metres**powers,
        ])
    si = columns[1.0]
    for metres in (1e3, 1e-3):
        scale = np.abs(si).max(axis=0)
        error = (np.abs(columns[metres] - si).max(axis=0) / scale)
        # The terms' own derivatives agree to round-off (measured 4e-14); a
        # differenced column to its differences' (a unit-free step: 1.5e-11).
        bound = np.array([1e-10 if p in DIFFERENCED else 1e-12 for p in PARAMETERS])
        assert np.all(error < bound), dict(zip(PARAMETERS, error, strict=True))


@pytest.mark.parametrize("metres", [1.0, 1e3, 1e-3], ids=["m", "mm", "km"])
@pytest.mark.parametrize("scheme", ["fd2", "fe4"])
def test_every_kind_matches_differences_of_whole_solves(scheme, metres):
    n = 24 if scheme == "fd2" else 12
    data = in_units(BASE, metres)
    solver = softspine.Solver(data, n_elements=n, scheme=scheme, residual_tol=TIGHT)
    base = solver.solve(check=True)
    sens = solver.sensitivity(PARAMETERS)
    analytic = np.vstack([sens.tip_position, sens.tip_rotation])
    for j, path in enumerate(PARAMETERS):
        box, key = at(data, path)
        # A five-point difference of whole solves with a step 1e-3 of the
        # parameter (its SI scale where it is zero): truncation 1e-12.
        h = 1e-3 * (abs(box[key]) or 0.01 * metres ** power_of(path))
        poses = [
            tip_pose(
                softspine.solve(moved(data, path, k * h), n_elements=n, scheme=scheme,
                                residual_tol=TIGHT),
                base.tip_quaternion,
            )
            for k in (2, 1, -1, -2)
        ]
        fd = (-poses[0] + 8 * poses[1] - 8 * poses[2] + poses[3]) / (12 * h)
        # Position rows relative to their largest, rotation rows to theirs.
        for rows in (slice(0, 3), slice(3, 6)):
            scale = np.abs(fd[rows]).max()
            assert np.abs(analytic[rows, j] - fd[rows]).max() <= 1e-7 * scale, (path, rows)


@pytest.mark.parametrize("scheme", ["fd2", "fe4"])
def test_a_differenced_column_is_exact_to_round_off(scheme):
    """A section's length moves the mesh: its column is differenced. Unloaded,
    the equilibrium is the rest shape at any length, exact to round-off, so
    five-point differences of whole solves give its derivative to 1e-12
    (not the solve's tolerance): the column must agree to 1e-11 of it
    (measured 2e-12; the second-order differences before were 1e-10 to 8e-10
    off)."""
    n = 24 if scheme == "fd2" else 12
    data = {key: BASE[key] for key in ("length", "stiffness", "rest_curvature")}
    data["sections"] = [{"length": s["length"], "stiffness": s["stiffness"]}
                        for s in BASE["sections"]]
    solver = softspine.Solver(data, n_elements=n, scheme=scheme)
    base = solver.solve(check=True)
    assert base.iterations == 0, "the rest shape is the exact equilibrium"
    parameters = ["sections[0].length", "sections[1].length"]
    sens = solver.sensitivity(parameters)
    assert not any(sens.exact)
    analytic = np.vstack([sens.tip_position, sens.tip_rotation])
    for j, path in enumerate(parameters):
        section = int(path[len("sections[")])
        h = 1e-3 * data["sections"][section]["length"]
        poses = []
        for k in (2, 1, -1, -2):
            scene = copy.deepcopy(data)
            scene["sections"][section]["length"] += k * h
            scene["length"] += k * h
            poses.append(tip_pose(softspine.solve(scene, n_elements=n, scheme=scheme),
                                  base.tip_quaternion))
        fd = (-poses[0] + 8 * poses[1] - 8 * poses[2] + poses[3]) / (12 * h)
        for rows in (slice(0, 3), slice(3, 6)):
            scale = np.abs(fd[rows]).max()
            assert np.abs(analytic[rows, j] - fd[rows]).max() <= 1e-11 * scale, (path, rows)


@pytest.mark.parametrize("scheme", ["fd2", "fe4"])
def test_a_tendon_routed_by_section_has_analytic_routing_columns(scheme):
    """Each routing's offset and twist is the tendon term's own parameter:
    an analytic column, equal to five-point differences of whole solves."""
    n = 24 if scheme == "fd2" else 12
    data = copy.deepcopy(BASE)
    data["tendons"] = [{"tension": 0.5, "offset": [[0.01, 0.0], [-0.004, 0.008]],
                        "twist": [0.3, -1.2]}]
    parameters = ["tendons[0].offset[0][1]", "tendons[0].offset[1][0]",
                  "tendons[0].twist[0]", "tendons[0].twist[1]"]
    solver = softspine.Solver(data, n_elements=n, scheme=scheme, residual_tol=TIGHT)
    base = solver.solve(check=True)
    sens = solver.sensitivity(parameters)
    assert all(sens.exact)
    analytic = np.vstack([sens.tip_position, sens.tip_rotation])
    for j, path in enumerate(parameters):
        box, key = at(data, path)
        h = 1e-3 * (abs(box[key]) or 0.01)
        poses = []
        for k in (2, 1, -1, -2):
            scene = copy.deepcopy(data)
            moved_box, moved_key = at(scene, path)
            moved_box[moved_key] += k * h
            poses.append(tip_pose(softspine.solve(scene, n_elements=n, scheme=scheme,
                                                  residual_tol=TIGHT), base.tip_quaternion))
        fd = (-poses[0] + 8 * poses[1] - 8 * poses[2] + poses[3]) / (12 * h)
        for rows in (slice(0, 3), slice(3, 6)):
            scale = np.abs(fd[rows]).max()
            assert np.abs(analytic[rows, j] - fd[rows]).max() <= 1e-7 * scale, (path, rows)


def test_a_pinned_tip_in_any_units_has_the_same_reaction_sensitivity():
    free = softspine.solve(BASE, n_elements=24, residual_tol=TIGHT)
    held = dict(BASE, tip={"type": "pinned",
                           "position": list(free.tip_position + [0.01, 0.0, -0.01])})
    parameters = ["tip_force[0]", "sections[1].stiffness.kx", "sections[0].length"]
    powers = np.array([power_of(p) for p in parameters], dtype=float)
    forces = {}
    for metres in (1.0, 1e3, 1e-3):
        solver = softspine.Solver(in_units(held, metres), n_elements=24, residual_tol=TIGHT)
        solver.solve(check=True)
        sens = solver.sensitivity(parameters)
        # A force per unit of p: metres^(power - 1) to SI.
        forces[metres] = sens.tip_reaction_force * metres ** (powers - 1.0)
    for metres in (1e3, 1e-3):
        scale = np.abs(forces[1.0]).max(axis=0)
        assert (np.abs(forces[metres] - forces[1.0]).max(axis=0) / scale).max() < 1e-9


@pytest.mark.parametrize("name, reason", [
    ("point_loads[0].s", "not differentiable"),
    ("length", "sections[i].length"),
])
def test_parameters_without_a_derivative_are_refused_by_name(name, reason):
    solver = softspine.Solver(BASE, n_elements=24)
    solver.solve(check=True)
    with pytest.raises(ValueError, match=re.escape(name) + ".*" + re.escape(reason)):
        solver.sensitivity([name])
