"""A tip force off the tip (a tool's weight and its payload): the scene's
``tip_force_offset`` against shooting on the Cosserat rod, and the robot's
``tool_mass`` and ``tool_offset``."""

from __future__ import annotations

import numpy as np
import pytest
from tendon_reference import solve_reference

import softspine

from closed_forms import observed_orders

SCENE = {
    "length": 1.0,
    "stiffness": {"kx": 0.5, "ky": 0.6, "kz": 0.4},
    "rest_curvature": [[0.4, -0.2]],
    "gravity": {"linear_density": 0.2, "vector": [0.0, 0.0, -9.81]},
    "tip_force": [0.3, -0.2, -0.8],
    "tip_force_offset": [0.05, -0.02, 0.12],   # m, the tip's frame
}


def test_the_offset_force_is_the_rods_tip_moment_at_second_and_fourth_order():
    """At the equilibrium, a force F acting at R c from the tip loads the rod
    with F and the moment (R c) x F. Shooting with that (constant) moment must
    give the same backbone: the scheme's error shrinks at its order."""
    fine = softspine.solve(SCENE, n_elements=128, scheme="fe4", residual_tol=1e-13)
    assert fine.converged and fine.stable
    arm = fine.rotation_matrices[-1] @ np.array(SCENE["tip_force_offset"])
    reference_scene = {k: v for k, v in SCENE.items() if k != "tip_force_offset"}
    reference_scene["tip_moment"] = list(np.cross(arm, SCENE["tip_force"]))
    reference = solve_reference(reference_scene, list(np.linspace(0, 1, 33)), rtol=1e-11)
    errors = {}
    for scheme, sizes in (("fd2", (8, 16, 32)), ("fe4", (4, 8, 16))):
        errors[scheme] = [
            np.abs(softspine.solve(SCENE, n_elements=n, scheme=scheme, residual_tol=1e-13)
                   .positions - reference[:: 32 // n]).max()
            for n in sizes
        ]
    assert all(1.8 < p < 2.2 for p in observed_orders(errors["fd2"])), errors
    assert all(3.6 < p < 4.4 for p in observed_orders(errors["fe4"])), errors
    # Without the offset the tip lands elsewhere: the test sees the offset.
    plain = softspine.solve({**SCENE, "tip_force_offset": [0, 0, 0]}, n_elements=32)
    assert np.linalg.norm(plain.tip_position - fine.tip_position) > 1e-2


def test_a_robots_tool_carries_its_weight_and_the_payload_at_its_offset():
    robot = softspine.Robot({"tool_mass": 0.02, "tool_offset": [0.0, 0.03, 0.05]})
    scene = robot.scene(np.zeros((10, 2)), load=0.01).to_dict()
    assert np.allclose(scene["tip_force"], [0, 0, -0.03 * 9.81])
    assert scene["tip_force_offset"] == [0.0, 0.03, 0.05]
    assert softspine.Robot(robot.to_dict()).to_dict() == robot.to_dict()
    kappa = [[1.5, 0.5]] * 10
    tool = robot.forward(kappa, load=0.01)
    at_tip = softspine.Robot({"tool_mass": 0.02}).forward(kappa, load=0.01)
    assert tool.converged and np.linalg.norm(tool.tip_position - at_tip.tip_position) > 1e-3
    # The sensitivity to the tool's mass against whole solves.
    sens = robot.sensitivity(kappa, load=0.01, parameters=["tool_mass"])
    h = 1e-5
    heavier = softspine.Robot({**robot.to_dict(), "tool_mass": 0.02 + h})
    difference = (heavier.forward(kappa, load=0.01).tip_position - tool.tip_position) / h
    assert np.allclose(sens.tip_position[:, 0], difference, rtol=1e-3, atol=1e-6)


def test_bad_tools_and_methods_that_cannot_carry_them_are_refused():
    with pytest.raises(ValueError, match="tool_offset"):
        softspine.Robot({"tool_offset": [0, np.nan, 0]})
    with pytest.raises(ValueError, match="tool_mass"):
        softspine.Robot({"tool_mass": -0.1})
    with pytest.raises(ValueError, match="tip_force_offset"):
        softspine.solve(SCENE, method="paper")
    with pytest.raises(ValueError, match="tip_force_offset"):
        softspine.solve({**SCENE, "tip_force_offset": [0, 0]})


def tool_point(sol, offset):
    return sol.tip_position + sol.rotation_matrices[-1] @ np.asarray(offset)


def test_inverse_kinematics_puts_the_tools_point_on_the_target():
    offset = [0.02, 0.0, 0.06]
    robot = softspine.Robot({"tool_mass": 0.015, "tool_offset": offset})
    target = tool_point(robot.forward([[1.2, -0.6]] * 10, load=0.01), offset)
    r = robot.inverse(target, load=0.01)
    assert r.reached, r.message
    assert np.linalg.norm(tool_point(r.solution, offset) - target) <= 1e-9
    assert np.allclose(r.tip_position, tool_point(r.solution, offset))
    # The backbone's tip is elsewhere: the offset is aimed, not the tip.
    assert np.linalg.norm(r.solution.tip_position - target) > 0.03
    # A tendon robot aims its tool the same way.
    tendons = [{"offset": [0.008 * np.cos(a), 0.008 * np.sin(a)], "section": s + 1}
               for s in range(3) for a in np.deg2rad([90, 210, 330]) + 0.7 * s]
    arm = softspine.Robot({"length": 0.3, "sections": 3, "base_quaternion": [1, 0, 0, 0],
                           "stiffness": {"E": 60e9, "G": 23e9, "diameter": 0.0015},
                           "linear_density": 0.05, "disk_mass": 0.0, "tendons": tendons,
                           "tool_mass": 0.005, "tool_offset": [0.0, 0.01, 0.03]})
    target = tool_point(arm.forward(tensions=[4, 0, 0, 0, 3, 0, 0, 0, 2.0]), [0.0, 0.01, 0.03])
    r = arm.inverse(target)
    assert r.reached, r.message
    assert np.linalg.norm(tool_point(r.solution, [0.0, 0.01, 0.03]) - target) <= 1e-9


def test_a_target_out_of_reach_is_measured_from_the_robots_base():
    # Regression: the distance was measured from the origin (3.5 m here).
    robot = softspine.Robot({"base_position": [0.0, 0.0, 5.0]})
    r = robot.inverse([0.0, 0.0, 3.5])
    assert r.ending == softspine.IkEnding.OUT_OF_REACH
    assert "1.5000 m from the base" in r.message, r.message
    # A target within reach of the moved base is reached.
    target = softspine.trajectories.circle(3, robot)[0]
    assert robot.inverse(target, load=0.03).reached
