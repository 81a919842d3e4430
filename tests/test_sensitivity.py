"""Sensitivities (`Solver.sensitivity`, `Robot.sensitivity`) against central
differences of whole solves, and `softspine.calibrate` on synthetic
measurements from known parameters."""

from __future__ import annotations

import numpy as np
import pytest

import softspine

TIGHT = 1e-13


def scene(**changes):
    data = {
        "length": 0.8,
        "stiffness": {"kx": 0.9, "ky": 1.1, "kz": 0.7},
        "rest_curvature": [[1.2, -0.4], [-0.6, 0.9]],
        "gravity": {"linear_density": 0.6, "vector": [0.0, 0.5, -9.81]},
        "tip_force": [0.8, -0.3, -0.5],
        "tip_moment": [0.05, 0.1, -0.02],
    }
    data.update(changes)
    return data


def tip_pose(sol, reference):
    """Tip position and the world-frame turn from `reference` (rotation vector)."""
    w, x, y, z = sol.tip_quaternion
    rw, rx, ry, rz = reference
    # q * conj(r)
    turn = np.array(
        [
            w * rw + x * rx + y * ry + z * rz,
            -w * rx + x * rw - y * rz + z * ry,
            -w * ry + x * rz + y * rw - z * rx,
            -w * rz - x * ry + y * rx + z * rw,
        ]
    )
    turn *= np.sign(turn[0])
    return np.concatenate([sol.tip_position, 2 * turn[1:]])


def test_the_tip_compliance_matches_differences_of_solves():
    solver = softspine.Solver(scene(), n_elements=20, residual_tol=TIGHT)
    sol = solver.solve(check=True)
    sens = solver.sensitivity("tip_wrench")
    assert sens.parameters[:3] == ["tip_force[0]", "tip_force[1]", "tip_force[2]"]
    assert sens.pose.shape == (6, 6)
    h = 1e-4
    for j, (key, axis) in enumerate(
        [("tip_force", a) for a in range(3)] + [("tip_moment", a) for a in range(3)]
    ):
        poses = []
        for sign in (1, -1):
            data = scene()
            data[key] = list(data[key])
            data[key][axis] += sign * h
            poses.append(
                tip_pose(
                    softspine.solve(data, n_elements=20, residual_tol=TIGHT), sol.tip_quaternion
                )
            )
        fd = (poses[0] - poses[1]) / (2 * h)
        np.testing.assert_allclose(sens.pose[:, j], fd, atol=1e-6 * max(1, np.abs(fd).max()))


@pytest.mark.parametrize("tip", ["pinned", "clamped"])
def test_held_tips_give_the_sensitivity_of_their_reactions(tip):
    free = softspine.solve(scene(), n_elements=20, residual_tol=TIGHT)
    held = {"type": tip, "position": list(free.tip_position + [0.01, 0.0, -0.01])}
    changes = {"tip": held}
    if tip == "clamped":
        held["quaternion"] = list(free.tip_quaternion)
        changes.update(tip_force=[0, 0, 0], tip_moment=[0, 0, 0])
    solver = softspine.Solver(scene(**changes), n_elements=20, residual_tol=TIGHT)
    solver.solve(check=True)
    sens = solver.sensitivity(["stiffness.kx", "gravity.linear_density"])
    assert sens.tip_reaction_force is not None
    assert (sens.tip_reaction_moment is not None) == (tip == "clamped")
    # A held tip does not move.
    np.testing.assert_allclose(sens.tip_position, 0, atol=1e-9)
    h = 1e-5
    for j, (outer, inner) in enumerate([("stiffness", "kx"), ("gravity", "linear_density")]):
        values = []
        for sign in (1, -1):
            data = scene(**changes)
            data[outer] = dict(data[outer])
            data[outer][inner] += sign * h
            values.append(
                softspine.solve(data, n_elements=20, residual_tol=TIGHT).tip_reaction_force
            )
        fd = (values[0] - values[1]) / (2 * h)
        np.testing.assert_allclose(
            sens.tip_reaction_force[:, j], fd, atol=1e-6 * max(1, np.abs(fd).max())
        )


def test_the_robot_sensitivity_to_its_actuation_and_fields():
    robot = softspine.Robot()
    kappa = robot.workspace(1, 0.03, seed=4).actuations[0]
    sens = robot.sensitivity(kappa, 0.03, ["rest_curvature", "stiffness.E", "load"])
    assert sens.solution is not None and sens.solution.converged
    assert sens.tip_position.shape == (3, 2 * robot.sections + 2)
    h = 1e-4 * robot.to_dict()["stiffness"]["E"]
    tips = []
    for sign in (1, -1):
        data = robot.to_dict()
        data["stiffness"]["E"] += sign * h
        tips.append(softspine.Robot(data).forward(kappa, 0.03).tip_position)
    fd = (tips[0] - tips[1]) / (2 * h)
    np.testing.assert_allclose(sens.tip_position[:, -2], fd, rtol=1e-5, atol=1e-20)


@pytest.mark.parametrize(
    ("call", "message"),
    [
        (lambda s, r: s.sensitivity("tip_force[7]"), "out of range"),
        (lambda s, r: s.sensitivity("stiffnes"), "no field"),
        (lambda s, r: s.sensitivity(3), "parameters"),
        (lambda s, r: r.sensitivity(np.zeros((10, 2)), parameters="sections"), "a count"),
        (
            lambda s, r: r.sensitivity(np.zeros((10, 2)), parameters="rest_curvature[10][0]"),
            "rest_curvature",
        ),
    ],
)
def test_bad_parameters_are_refused_by_name(call, message):
    solver = softspine.Solver(scene(), n_elements=20)
    solver.solve()
    with pytest.raises(ValueError, match=message):
        call(solver, softspine.Robot())


def test_a_sensitivity_needs_a_solved_state():
    with pytest.raises(ValueError, match="solve first"):
        softspine.Solver(scene(), n_elements=20).sensitivity("tip_wrench")


def test_calibration_recovers_known_parameters():
    truth = softspine.Robot()
    ws = truth.workspace(30, 0.03, seed=21)
    start = truth.to_dict()
    start["stiffness"]["E"] *= 1.3
    start["linear_density"] *= 0.7
    names = ["stiffness.E", "linear_density"]
    true_values = np.array([truth.to_dict()["stiffness"]["E"], truth.to_dict()["linear_density"]])
    # Without noise: the truth, to the forward solves' tolerance.
    fit = softspine.calibrate(
        softspine.Robot(start), ws.actuations, ws.tip_positions, names, load=0.03
    )
    assert fit.converged, fit.message
    np.testing.assert_allclose(fit.estimates, true_values, rtol=1e-8)
    # With noise: the errors over their reported standard errors behave like
    # standard normal deviates (12 noise draws; E and the density are
    # 99.5 % correlated here, which the standard errors must carry).
    sigma = 3e-4
    scores = []
    for seed in range(12):
        rng = np.random.default_rng(seed)
        measured = ws.tip_positions + sigma * rng.standard_normal(ws.tip_positions.shape)
        fit = softspine.calibrate(softspine.Robot(start), ws.actuations, measured, names, load=0.03)
        assert fit.converged, fit.message
        assert 0.7 * sigma < fit.rms < 1.3 * sigma
        assert np.all(fit.standard_errors < 0.05 * true_values)
        scores.append((fit.estimates - true_values) / fit.standard_errors)
    scores = np.array(scores)
    assert np.abs(scores).max() < 4.5, scores
    assert 0.6 < np.sqrt(np.mean(scores**2)) < 1.6, scores
    assert fit.residuals.shape == (30, 3)
    assert fit.robot.to_dict()["linear_density"] == fit.estimates[1]
    assert set(fit.summary()) == set(names)


def test_calibration_refuses_what_it_cannot_fit():
    robot = softspine.Robot()
    k = np.zeros((3, robot.sections, 2))
    tips = np.zeros((3, 3))
    with pytest.raises(ValueError, match="actuation is known"):
        softspine.calibrate(robot, k, tips, ["rest_curvature"])
    with pytest.raises(ValueError, match="measured_tips"):
        softspine.calibrate(robot, k, np.zeros((3, 2)), ["linear_density"])
    with pytest.raises(ValueError, match="actuations"):
        softspine.calibrate(robot, k[:2], tips, ["linear_density"])


def test_the_payload_sensitivity_at_no_payload_differences_through_zero():
    # At load=0 the central difference stepped to a negative mass, refused as
    # "load: must be a mass >= 0 kg" (3e30b16); the tip force is linear in it.
    robot = softspine.Robot()
    kappa = np.full((robot.sections, 2), 0.5)
    sens = robot.sensitivity(kappa, 0.0, parameters="load")
    h = 1e-3
    one_sided = (robot.forward(kappa, h).tip_position - robot.forward(kappa, 0.0).tip_position) / h
    np.testing.assert_allclose(sens.tip_position[:, 0], one_sided, rtol=1e-2)
