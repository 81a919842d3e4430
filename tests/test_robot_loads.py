"""What a robot carries besides its own weight: a payload mass, a tip wrench
and point wrenches (world frame), in forward, inverse, tracking, batches,
sensitivities and calibration; checked against closed forms and against the
payload's own path, and refused by name when malformed."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import softspine

EXAMPLES = Path(__file__).resolve().parent.parent / "examples" / "robots"


def tendon_robot() -> softspine.Robot:
    return softspine.Robot.from_file(EXAMPLES / "tendon_robot.toml")


def test_a_payload_is_its_weight_as_a_tip_force():
    """`load=m` and `load={"tip_force": m g}` are the same robot: two paths
    through the core (the mass along the robot's gravity, the force as given)."""
    robot = softspine.Robot()
    kappa = np.array([[0.8, -0.3]] * robot.sections)
    mass = robot.forward(kappa, load=0.03)
    force = robot.forward(kappa, load={"tip_force": [0.0, 0.0, -9.81 * 0.03]})
    assert mass.converged and force.converged
    np.testing.assert_allclose(force.positions, mass.positions, rtol=0, atol=1e-12)
    both = robot.forward(kappa, load={"mass": 0.01, "tip_force": [0.0, 0.0, -9.81 * 0.02]})
    np.testing.assert_allclose(both.positions, mass.positions, rtol=0, atol=1e-12)


def test_a_tip_moment_bends_a_weightless_robot_into_an_arc():
    """Closed form: a pure end moment M bends a weightless rod into an arc of
    curvature M / EI, its tip at ((1 - cos kL) / k, 0, sin kL / k) from a base
    along +z."""
    robot = softspine.Robot({"sections": 2, "n_elements": 64, "gravity": [0, 0, 0],
                             "base_quaternion": [1, 0, 0, 0]})
    stiffness = robot.to_dict()["stiffness"]
    ei = stiffness["E"] * np.pi * stiffness["diameter"] ** 4 / 64
    length = robot.to_dict()["length"]
    moment = 0.5 * np.pi * ei / length  # a quarter turn
    sol = robot.forward(np.zeros((2, 2)), load={"tip_moment": [0.0, moment, 0.0]})
    k = moment / ei
    expected = [(1 - np.cos(k * length)) / k, 0.0, np.sin(k * length) / k]
    # Second order in n = 64 elements: 1e-4 L covers the scheme's error.
    np.testing.assert_allclose(sol.tip_position, expected, rtol=0, atol=1e-4 * length)
    fine = softspine.Robot({**robot.to_dict(), "n_elements": 128})
    fine_tip = fine.forward(np.zeros((2, 2)), load={"tip_moment": [0.0, moment, 0.0]})
    # ... and the error falls by four when n doubles.
    ratio = (np.linalg.norm(sol.tip_position - expected)
             / np.linalg.norm(fine_tip.tip_position - expected))
    assert 3.5 < ratio < 4.5, ratio


def test_a_point_load_acts_where_it_is_put():
    """A point force at the tip node and the same tip force are one load; at
    mid-length it bends the robot less."""
    robot = tendon_robot()
    tensions = [6.0, 0, 0, 0, 5.0, 0, 0, 0, 4.0]
    length = robot.to_dict()["length"]
    force = [0.3, 0.0, 0.0]
    tip = robot.forward(tensions=tensions, load={"tip_force": force})
    point = robot.forward(tensions=tensions,
                          load={"point_loads": [{"s": length, "force": force}]})
    np.testing.assert_allclose(point.positions, tip.positions, rtol=0, atol=1e-12)
    free = robot.forward(tensions=tensions)
    mid = robot.forward(tensions=tensions,
                        load={"point_loads": [{"s": length * 14 / 21, "force": force}]})
    push = lambda sol: (sol.tip_position - free.tip_position)[0]  # noqa: E731
    assert 0 < push(mid) < push(tip)


def test_the_ik_reaches_a_target_under_a_lateral_tip_force():
    """The tendon-robot experiment: a lateral force at the tip. The tensions
    found put the loaded tip on the target; ignoring the force misses."""
    robot = tendon_robot()
    load = {"mass": 0.02, "tip_force": [0.4, -0.2, 0.0]}
    target = robot.forward(tensions=[6.0, 0, 0, 0, 5.0, 0, 0, 0, 4.0], load=load).tip_position
    r = robot.inverse(target, load=load)
    assert r.reached, r.message
    again = robot.forward(tensions=r.tensions, load=load)
    assert np.linalg.norm(again.tip_position - target) < 1e-9
    unaware = robot.forward(tensions=robot.inverse(target, load=0.02).tensions, load=load)
    assert np.linalg.norm(unaware.tip_position - target) > 1e-3
    solver = robot.inverse_solver(load)
    assert np.allclose(solver.solve(target).tensions, r.tensions, atol=1e-6)
    tracked = robot.track([target, target + [0.005, 0, 0]], load=load)
    assert all(t.reached for t in tracked)


def test_batches_sensitivities_and_calibration_take_the_load():
    robot = tendon_robot()
    load = {"tip_force": [0.3, 0.0, 0.0], "tip_moment": [0.0, 0.01, 0.0]}
    tensions = np.array([[6.0, 0, 0, 0, 5.0, 0, 0, 0, 4.0], [0, 3.0, 0, 4.0, 0, 0, 2.0, 0, 0]])
    batch = robot.forward_batch(tensions=tensions, load=load, threads=1, progress=False)
    for i, t in enumerate(tensions):
        one = robot.forward(tensions=t, load=load)
        np.testing.assert_allclose(batch.tip_positions[i], one.tip_position, rtol=0, atol=1e-12)
    found = robot.inverse_batch(batch.tip_positions, load=load, threads=1, progress=False)
    assert found.reached.all()
    sens = robot.sensitivity(tensions=tensions[0], load=load, parameters="tensions")
    step = np.zeros(9)
    step[0] = 1e-4
    moved = robot.forward(tensions=tensions[0] + step, load=load).tip_position
    back = robot.forward(tensions=tensions[0] - step, load=load).tip_position
    np.testing.assert_allclose(sens.tip_position[:, 0], (moved - back) / (2 * step[0]),
                               rtol=1e-6, atol=1e-12)


def test_the_pneumatic_calibration_takes_a_wrench():
    """Calibration under a wrench recovers the modulus the tips were made
    with (and a fit that ignores the wrench does not)."""
    truth = softspine.Robot({"sections": 2, "n_elements": 10})
    kappa = np.array([[[1.0, 0.0], [0.5, 0.5]], [[-0.5, 1.0], [0.0, -1.0]],
                      [[0.2, 0.3], [-1.0, 0.4]]])
    load = {"mass": 0.02, "tip_force": [0.05, 0.0, 0.0]}
    tips = [truth.forward(k, load=load).tip_position for k in kappa]
    start = truth.to_dict()
    start["stiffness"]["E"] *= 1.3
    fit = softspine.calibrate(softspine.Robot(start), kappa, tips, "stiffness.E", load=load)
    assert fit.converged, fit.message
    np.testing.assert_allclose(fit.estimates, [200e9], rtol=1e-8)
    blind = softspine.calibrate(softspine.Robot(start), kappa, tips, "stiffness.E", load=0.02)
    assert abs(blind.estimates[0] / 200e9 - 1) > 1e-3


@pytest.mark.parametrize(("load", "message"), [
    ({"tip_force": [1.0, 2.0]}, r"load\.tip_force"),
    ({"tip_forse": [1.0, 0, 0]}, r"tip_forse"),
    ({"mass": -1.0}, r"load\.mass: must be a mass >= 0 kg"),
    ({"tip_moment": [np.nan, 0, 0]}, r"load\.tip_moment"),
    ("heavy", r"load: expected a mass \[kg\] or a dict"),
    ({"point_loads": [{"s": 0.1}]}, r"load\.point_loads\[0\]"),
    ({"tip_force": [1e12, 0, 0]}, r"load\.tip_force: the tip force is .* times what bends"),
])
def test_a_malformed_load_is_refused_by_name(load, message):
    with pytest.raises(ValueError, match=message):
        tendon_robot().forward(tensions=[1.0] * 9, load=load)


@pytest.mark.parametrize(
    "call",
    [
        lambda r: r.forward(None, 30.0),
        lambda r: r.forward_batch(np.zeros((1, r.sections, 2)), 30.0, progress=False),
        lambda r: r.workspace(1, 30.0, progress=False),
        lambda r: r.inverse_batch([[0.1, 0.0, -0.8]], 30.0, progress=False),
        lambda r: r.sensitivity(None, 30.0),
        lambda r: softspine.calibrate(
            r, np.zeros((1, r.sections, 2)), [[0.0, 0.0, -1.0]], "disk_mass", 30.0
        ),
    ],
    ids=["forward", "forward_batch", "workspace", "inverse_batch", "sensitivity", "calibrate"],
)
def test_a_load_warning_points_at_the_callers_line(call):
    # The batches and sensitivities go through the package's Python layer; the
    # warning skipped only one frame and pointed into softspine/batch.py.
    with pytest.warns(UserWarning, match="grams meant") as record:
        call(softspine.Robot())
    assert record[0].filename == __file__


def test_the_tip_sensitivity_to_the_loads_wrench_is_the_forward_difference():
    robot = softspine.Robot()
    kappa = robot.rest_curvature(np.full((robot.sections, 3), 0.095))
    kappa[2] = [1.5, -0.5]
    load = {"mass": 0.02, "tip_force": [0.1, 0.0, 0.0],
            "point_loads": [{"s": 0.5, "force": [0.0, 0.05, 0.0], "moment": [0.0, 0.0, 0.01]}]}
    names = ["load.tip_force", "load.tip_moment[1]", "load.point_loads[0].moment[2]", "load.mass"]
    sens = robot.sensitivity(kappa, load, names)
    assert sens.parameters == [
        "load.tip_force[0]", "load.tip_force[1]", "load.tip_force[2]", "load.tip_moment[1]",
        "load.point_loads[0].moment[2]", "load.mass",
    ]

    def tip(column, h):
        moved = {**load, "tip_moment": [0.0, 0.0, 0.0],
                 "point_loads": [dict(load["point_loads"][0])]}
        moved["tip_force"] = list(load["tip_force"])
        moved["point_loads"][0]["moment"] = [0.0, 0.0, 0.01]
        if column < 3:
            moved["tip_force"][column] += h
        elif column == 3:
            moved["tip_moment"] = [0.0, h, 0.0]
        elif column == 4:
            moved["point_loads"][0]["moment"] = [0.0, 0.0, 0.01 + h]
        else:
            moved["mass"] = 0.02 + h
        return robot.forward(kappa, moved).tip_position

    for column in range(6):
        h = 1e-4
        difference = (tip(column, h) - tip(column, -h)) / (2 * h)
        np.testing.assert_allclose(
            sens.tip_position[:, column], difference, rtol=1e-6, atol=1e-9,
            err_msg=sens.parameters[column],
        )


def test_calibration_finds_an_unknown_tip_force_from_measured_tips():
    # Force sensing: the tips of 12 known actuations under an unknown lateral
    # tip force give the force back.
    robot = softspine.Robot()
    force = [0.08, -0.05, 0.0]
    drives = robot.workspace(12, 0.0, seed=4, progress=False).actuations
    measured = robot.forward_batch(drives, {"tip_force": force}, progress=False).tip_positions
    fit = softspine.calibrate(robot, drives, measured, "load.tip_force", {"tip_force": [0, 0, 0]})
    assert fit.converged, fit.message
    assert fit.parameters == ["load.tip_force[0]", "load.tip_force[1]", "load.tip_force[2]"]
    np.testing.assert_allclose(fit.estimates, force, atol=1e-7)


@pytest.mark.parametrize(
    ("name", "message"),
    [
        ("load.point_loads[0].s", "^parameters\\[0\\]: 'load.point_loads\\[0\\].s': expected"),
        ("load.force", "^parameters\\[0\\]: 'load.force': expected load.mass"),
        ("load.tip_force[3]", r"'load.tip_force\[3\]': a component is \[0\], \[1\] or \[2\]"),
        ("load.point_loads[2].force", r"^load.point_loads\[2\].force\[0\]: not in the load, which"),
    ],
)
def test_a_wrench_parameter_that_does_not_exist_is_refused_by_name(name, message):
    robot = softspine.Robot()
    load = {"point_loads": [{"s": 0.5, "force": [0.0, 0.05, 0.0]}]}
    with pytest.raises(ValueError, match=message):
        robot.sensitivity(None, load, name)
