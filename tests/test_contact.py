"""Frictionless contact with rigid obstacles (issue 28): the solver against
closed forms (docs/model.md, "Contact with obstacles") and against the
shooting reference of tests/contact_reference.py, exact checks that need no
reference (no point of any chord inside an obstacle, forces that push, the
forces' balance), and the refusals of what is not supported yet."""

from __future__ import annotations

import math
import re
import warnings

import numpy as np
import pytest
from contact_reference import between_walls, clamped_pinned, lifted_rod, rod_in_bend

import softspine

# The material z axis (the tangent) along world +x.
ALONG_X = [math.sqrt(0.5), 0.0, math.sqrt(0.5), 0.0]
TABLE = {"shape": "half_space", "point": [0.0, 0.0, 0.0], "normal": [0.0, 0.0, 1.0]}


def heavy_rod(length: float, ei: float = 1.0, w: float = 1.0, **extra) -> dict:
    """A heavy rod along +x from the origin above (or on) a table."""
    scene = {
        "length": length,
        "stiffness": {"kx": ei, "ky": ei, "kz": ei},
        "gravity": {"linear_density": w, "vector": [0.0, 0.0, -1.0]},
        "base_quaternion": ALONG_X,
        "obstacles": [TABLE],
    }
    scene.update(extra)
    return scene


def lift_off(sol) -> float:
    """The arc length of the first contact."""
    return float(sol.contacts["arc_length"].min())


def test_a_rod_held_horizontal_above_a_table_meets_the_closed_form():
    # Small lift: a = (72 EI h / w)^(1/4); the table carries what the
    # clamp does not.
    ei, w, lift, length = 2.0, 3.0, 1e-4, 2.0
    a = (72.0 * ei * lift / w) ** 0.25
    for n in (40, 80):
        sol = softspine.solve(heavy_rod(length, ei, w, base_position=[0, 0, lift]),
                              n_elements=n)
        assert sol.converged and sol.stable, sol.message
        assert abs(lift_off(sol) - a) <= length / n
        # Forces push, the table carries the rest of the weight.
        assert (sol.contacts["force"] >= 0.0).all()
        assert sol.contacts["force"].sum() - sol.forces[0, 2] == pytest.approx(w * length,
                                                                              rel=1e-9)
        # The contacts lie on the table, the force along its normal.
        np.testing.assert_allclose(sol.contacts["point"][:, 2], 0.0, atol=1e-12)
        np.testing.assert_allclose(sol.contacts["normal"], [[0.0, 0.0, 1.0]] * len(
            sol.contacts["force"]))
        # Every node above the table, to the position rows' tolerance.
        assert sol.positions[:, 2].min() >= -sol.residual_norm * length - 1e-10 * length


@pytest.mark.parametrize("horizontal", [False, True])
def test_a_large_lift_meets_the_shooting_reference(horizontal):
    # h = 0.3 on a rod of 3 (the small-slope theory is 1 % off): the lifted
    # length within a grid step, and the lifting force (the end's vertical
    # force) at the scheme's second order.
    ei, w, lift, length = 1.0, 1.0, 0.3, 3.0
    a, force = lifted_rod(ei, w, lift, horizontal)
    errors = []
    for n in (60, 240):
        if horizontal:
            # The lifted end is the clamped base, held horizontal at h.
            sol = softspine.solve(heavy_rod(length, ei, w, base_position=[0, 0, lift]),
                                  n_elements=n)
            lifted = lift_off(sol)
            # What the clamp exerts on the rod, upwards.
            end_force = -sol.forces[0, 2]
            errors.append(abs(end_force - force))
        else:
            # The lifted end is the free tip, lifted by the reference's force.
            sol = softspine.solve(heavy_rod(length, ei, w, tip_force=[0, 0, force]),
                                  n_elements=n)
            lifted = length - float(sol.contacts["arc_length"].max())
            errors.append(abs(sol.tip_position[2] - lift))
        assert sol.converged and sol.stable, sol.message
        assert abs(lifted - a) <= length / n, (n, lifted, a)
    # Second order away from the lift-off point, which sits on a node: the
    # error falls by 15 and 19 over a factor 4 in n (measured), more than
    # the first order's 4.
    assert errors[1] < 1e-4 * lift
    assert errors[0] / errors[1] > 8.0, errors


def test_the_lifted_end_converges_at_second_order():
    # Lifted by a force F alone: a = 2 F / w, h = w a^4 / (24 EI) in the
    # small-deflection limit; the discrete tip height converges to the
    # continuous rod's at order 2 (its own limit, not the linear theory's).
    a = 0.3
    heights = []
    for n in (40, 80, 160):
        sol = softspine.solve(heavy_rod(2.0, tip_force=[0, 0, 0.5 * a]), n_elements=n)
        assert sol.converged, sol.message
        heights.append(sol.tip_position[2])
    ratio = (heights[1] - heights[0]) / (heights[2] - heights[1])
    assert 3.5 < ratio < 4.5, heights
    assert heights[2] == pytest.approx(a**4 / 24.0, rel=2e-3)


def test_no_chord_passes_through_a_sphere_between_two_nodes():
    # A coarse rod sags onto a small ball that fits between two nodes: the
    # contact is inside an element, and no point of any chord is inside.
    radius = 0.02
    ball = {"shape": "sphere", "centre": [0.45, 0.0, -0.03 - radius], "radius": radius}
    scene = {
        "length": 1.0,
        "stiffness": {"kx": 1.0, "ky": 1.0, "kz": 1.0},
        "gravity": {"linear_density": 1.0, "vector": [0.0, 0.0, -1.0]},
        "base_quaternion": ALONG_X,
        "obstacles": [ball],
    }
    sol = softspine.solve(scene, n_elements=10)
    assert sol.converged and sol.stable, sol.message
    contacts = sol.contacts
    assert len(contacts["force"]) == 1
    s = contacts["arc_length"][0]
    assert not np.isclose(s * 10, np.round(s * 10), atol=1e-6), "inside an element"
    assert contacts["force"][0] > 0.0
    # Every chord keeps out of the ball, touching it at the contact.
    p, centre = sol.positions, np.array(ball["centre"])
    chord = p[1:] - p[:-1]
    t = np.clip(np.einsum("ij,ij->i", centre - p[:-1], chord)
                / np.einsum("ij,ij->i", chord, chord), 0.0, 1.0)
    distance = np.linalg.norm(p[:-1] + t[:, None] * chord - centre, axis=1)
    assert distance.min() == pytest.approx(radius, abs=1e-11)
    np.testing.assert_allclose(np.linalg.norm(contacts["point"][0] - ball["centre"]), radius)
    # Without the ball the rod sags through it.
    free = softspine.solve({k: v for k, v in scene.items() if k != "obstacles"},
                           n_elements=10)
    assert np.linalg.norm(free.positions_at(np.array([s]))[0] - ball["centre"]) < radius


def test_a_rod_of_radius_keeps_its_surface_off_the_table():
    # The radius from a round rod's diameter, or given.
    scene = heavy_rod(1.0, base_position=[0, 0, 0.01])
    scene["stiffness"] = {"E": 1e6, "G": 4e5, "diameter": 0.01}
    sol = softspine.solve(scene, n_elements=20)
    assert sol.converged, sol.message
    assert sol.positions[:, 2].min() == pytest.approx(0.005, abs=1e-12)
    scene["radius"] = 0.008
    sol = softspine.solve(scene, n_elements=20)
    assert sol.positions[:, 2].min() == pytest.approx(0.008, abs=1e-12)


def test_contacts_survive_a_round_trip():
    sol = softspine.solve(heavy_rod(2.0, base_position=[0, 0, 1e-3]), n_elements=20)
    back = softspine.Solution.from_dict(sol.to_dict())
    for key, value in sol.contacts.items():
        np.testing.assert_array_equal(back.contacts[key], value)
    assert len(softspine.solve({"length": 1.0, "stiffness": {"kx": 1, "ky": 1, "kz": 1}},
                               n_elements=4).contacts["force"]) == 0


@pytest.mark.parametrize(("option", "field"), [({"scheme": "fe4"}, "scheme"),
                                                ({"method": "lm"}, "method"),
                                                ({"method": "shooting"}, "method"),
                                                ({"method": "paper"}, "method")])
def test_what_contact_does_not_support_yet_is_refused(option, field):
    with pytest.raises(ValueError, match=field):
        softspine.solve(heavy_rod(1.0), n_elements=10, **option)


@pytest.mark.parametrize(("obstacle", "field", "reason"), [
    ({"shape": "cone"}, "obstacles[0].shape", "unknown shape"),
    ({"shape": "sphere", "centre": [0, 0, 0], "radius": -1.0}, "obstacles[0].radius",
     "positive"),
    ({"shape": "half_space", "point": [0, 0, 0], "normal": [0, 0, 0]},
     "obstacles[0].normal", "zero"),
    ({"shape": "sphere", "centre": [0, float("nan"), 0], "radius": 1.0},
     "obstacles[0].centre", "finite"),
])
def test_bad_obstacles_are_refused_by_name(obstacle, field, reason):
    scene = heavy_rod(1.0)
    scene["obstacles"] = [obstacle]
    with pytest.raises(ValueError, match=rf"{re.escape(field)}.*{reason}"):
        softspine.solve(scene, n_elements=10)


def test_a_negative_radius_is_refused():
    with pytest.raises(ValueError, match="radius.*negative"):
        softspine.solve(heavy_rod(1.0, radius=-0.1), n_elements=10)


def along_x_turned(theta: np.ndarray) -> np.ndarray:
    """The frames of a planar backbone whose tangent makes the angles
    `theta` with +x in the x-y plane: ALONG_X turned about z."""
    c, s = np.cos(theta / 2), np.sin(theta / 2)
    return quaternion_product([c, 0 * c, 0 * c, s], ALONG_X).T


# The compressive load at which a clamped-clamped column buckles
# antisymmetrically (its second mode), over EI / L^2.
SECOND_MODE = 8.183 * math.pi**2


@pytest.mark.parametrize("span", [0.974, 0.9735])
def test_an_elastica_pressed_between_walls_meets_the_shooting_reference(span):
    # Domokos, Holmes and Royce's elastica between two walls 0.2 apart,
    # clamped at both ends: compressed to `span`, it touches the upper wall
    # at its middle. The force and shape against the shooting reference at
    # second order; and its stability: the middle held on the wall, each
    # half is a clamped-pinned column, so the state turns unstable where the
    # compression passes the column's antisymmetric buckling load 80.76
    # EI / L^2 (75.1 at span 0.974: stable; 89.3 at 0.9735: unstable, which
    # a solve used to report as not converged, its contacts lost). Stiff out
    # of the plane (ky): an isotropic rod leaves it, the walls only in y.
    gap = 0.1
    ref = between_walls(1.0, 1.0, span, gap)
    assert ref["regime"] == "point"
    (s_ref, force_ref), = ref["contacts"]
    scene = {"length": 1.0, "stiffness": {"kx": 1.0, "ky": 100.0, "kz": 1.0},
             "base_quaternion": ALONG_X,
             "tip": {"type": "clamped", "position": [span, 0.0, 0.0], "quaternion": ALONG_X},
             "obstacles": [{"shape": "half_space", "point": [0, gap, 0], "normal": [0, -1, 0]},
                           {"shape": "half_space", "point": [0, -gap, 0], "normal": [0, 1, 0]}]}
    force_errors, shape_errors = [], []
    for n in (20, 40, 80):
        s = np.linspace(0.0, 1.0, n + 1)
        # A start bent towards the upper wall picks the branch.
        start = along_x_turned(np.arctan(gap * np.pi * np.sin(2 * np.pi * s)))
        sol = softspine.solve(scene, n_elements=n, initial=start)
        assert sol.converged, sol.message
        assert sol.stable == (ref["compression"] < SECOND_MODE), (n, sol.message)
        contacts = sol.contacts
        assert contacts["obstacle"].tolist() == [0]
        assert contacts["arc_length"][0] == pytest.approx(s_ref)
        force_errors.append(abs(contacts["force"][0] - force_ref))
        shape_errors.append(np.abs(sol.positions[:, 1] - ref["y"](s)).max())
    assert force_errors[-1] < 1e-2 * force_ref and shape_errors[-1] < 2e-5
    for errors in (force_errors, shape_errors):
        assert errors[0] / errors[1] > 3.5 and errors[1] / errors[2] > 3.5, errors


# The robot among obstacles: the seed's robot (hanging, 1 m) with 30 g.
WALL = {"shape": "half_space", "point": [0.15, 0.0, 0.0], "normal": [-1.0, 0.0, 0.0]}


def test_a_robot_bent_into_a_wall_leans_on_it():
    robot = softspine.Robot({"obstacles": [WALL]})
    bend = np.zeros((10, 2))
    bend[:, 1] = 0.6
    free = softspine.Robot().forward(bend, load=0.03)
    sol = robot.forward(bend, load=0.03)
    assert free.positions[:, 0].max() > 0.15
    assert sol.converged and sol.stable, sol.message
    # The surface (the muscles, 2 cm off the backbone) touches the wall.
    assert sol.positions[:, 0].max() == pytest.approx(0.13, abs=1e-10)
    assert len(sol.contacts["force"]) >= 1 and (sol.contacts["force"] > 0).all()
    np.testing.assert_allclose(sol.contacts["point"][:, 0], 0.15, atol=1e-10)
    # The robot's dict keeps its obstacles and radius.
    again = softspine.Robot(softspine.Robot({"obstacles": [WALL], "radius": 0.03}).to_dict())
    assert again.to_dict()["obstacles"] == [WALL] and again.to_dict()["radius"] == 0.03


BALL = {"shape": "sphere", "centre": [0.2, 0.0, -0.75], "radius": 0.1}


def test_a_robot_whose_rest_shape_runs_through_a_ball_leans_on_its_near_side():
    # Bent 0.6 /m the rest shape runs through the ball; the solve starts
    # from the free equilibrium (less deep in it, not through it) and ends
    # where Newton from the rest shape itself ends, on the ball's near side.
    bend = np.zeros((10, 2))
    bend[:, 1] = 0.6
    robot = softspine.Robot({"obstacles": [BALL]})
    rest = softspine.Robot().forward(bend, load=0.0)
    centre = np.array(BALL["centre"])
    assert np.linalg.norm(rest.positions - centre, axis=1).min() < 0.1
    sol = robot.forward(bend, load=0.03)
    assert sol.converged and sol.stable, sol.message
    assert len(sol.contacts["force"]) == 1 and sol.contacts["normal"][0, 0] < -0.9
    # The surface (2 cm off the backbone) touches the ball, nowhere inside.
    distance = np.linalg.norm(sol.positions - centre, axis=1)
    assert distance.min() > 0.12 - 1e-9
    from_rest = robot.forward(bend, load=0.03, initial=rest.quaternions)
    assert from_rest.converged
    np.testing.assert_allclose(sol.positions, from_rest.positions, atol=1e-9)
    np.testing.assert_allclose(sol.contacts["force"], from_rest.contacts["force"], rtol=1e-8)


def test_a_robot_deep_in_a_wall_and_a_ball_leans_on_the_wall_alone():
    # A wall 5 cm off the axis in front of the ball: the rest shape runs
    # deep into both, the answer touches the wall only, as without the
    # ball. The start is chosen by the ball (its gap is far from linear
    # there), not by the wall, the deeper: from the rest shape the direct
    # solve's QP cycled.
    bend = np.zeros((10, 2))
    bend[:, 1] = 0.6
    wall = {"shape": "half_space", "point": [0.05, 0.0, 0.0], "normal": [-1.0, 0.0, 0.0]}
    sol = softspine.Robot({"obstacles": [wall, BALL]}).forward(bend, load=0.03)
    alone = softspine.Robot({"obstacles": [wall]}).forward(bend, load=0.03)
    assert sol.converged and sol.stable and sol.continuation_steps == 0, sol.message
    assert list(sol.contacts["obstacle"]) == [0]
    np.testing.assert_allclose(sol.positions, alone.positions, atol=1e-9)


FLOOR_60_CM = {"shape": "half_space", "point": [0.0, 0.0, -0.6], "normal": [0.0, 0.0, 1.0]}


def test_a_robot_hanging_closer_to_a_floor_than_its_length_is_set_down_on_it():
    # The 1 m robot bent 0.1 /m, its base 60 cm above a floor: its rest
    # shape and the straight rod both pass through the floor, so neither
    # Newton from rest nor the curl from straight has a start (before, no
    # convergence after 247 iterations). The floor is moved in from below
    # the free equilibrium instead; the same answer as raising the floor
    # by hand in warm steps through the public API.
    bend = np.zeros((10, 2))
    bend[:, 1] = 0.1
    sol = softspine.Robot({"obstacles": [FLOOR_60_CM]}).forward(bend, load=0.03)
    assert sol.converged and sol.stable, sol.message
    assert "moved in" in sol.message
    radius = 0.02
    assert sol.positions[:, 2].min() >= -0.6 + radius - 1e-9
    assert np.all(sol.contacts["force"] > 0) and np.all(sol.contacts["obstacle"] == 0)
    assert sol.positions[-1, 0] > 0.3  # laid down toward its bend
    free = softspine.Robot().forward(bend, load=0.03)
    height, last = free.positions[:, 2].min() - 0.01, free
    while height < -0.6:
        height = min(height + 0.1, -0.6)
        floor = dict(FLOOR_60_CM, point=[0.0, 0.0, height])
        last = softspine.Robot({"obstacles": [floor]}).forward(bend, load=0.03, initial=last)
        assert last.converged and last.stable, (height, last.message)
    np.testing.assert_allclose(sol.positions, last.positions, atol=1e-9)


def test_a_straight_robot_pressed_along_its_axis_into_a_floor_says_why_it_fails():
    # Straight and loaded along its axis, the rod buckles to a side that
    # nothing chooses: refused with that reason, not a bare "no convergence".
    sol = softspine.Robot({"obstacles": [FLOOR_60_CM]}).forward(np.zeros((10, 2)), load=0.03)
    assert not sol.converged
    assert "free equilibrium is straight" in sol.message and "buckles" in sol.message


def test_a_robot_hanging_through_a_slab_is_refused_with_the_side_missing_and_rests_on_it_from_one():
    # The robot's rest shape and its free equilibrium pass through a slab 4 cm
    # thick under its base from side to side: which side it rests on is its
    # history's. Moving the slab in from its middle pushes the rod out of
    # both faces at once: the solve fails, and says so (before, only that the
    # approach ran out of iterations). Started on the top face it rests on it.
    bend = np.zeros((10, 2))
    bend[:, 1] = 0.6
    slab = {"shape": "box", "centre": [0.0, 0.0, -0.5], "half_extents": [0.3, 0.3, 0.02]}
    robot = softspine.Robot({"obstacles": [slab]})
    sol = robot.forward(bend, load=0.03)
    assert not sol.converged
    assert "passes through obstacles[0] from side to side" in sol.message, sol.message
    assert "initial=" in sol.message
    top = {"shape": "half_space", "point": [0.0, 0.0, -0.48], "normal": [0.0, 0.0, 1.0]}
    on_top = softspine.Robot({"obstacles": [top]}).forward(bend, load=0.03)
    sol = robot.forward(bend, load=0.03, initial=on_top)
    assert sol.converged and sol.stable, sol.message
    assert len(sol.contacts["force"]) >= 1 and np.all(sol.contacts["force"] > 0)
    assert sol.contacts["normal"][:, 2].min() > 0.5  # on the top face or its edge
    radius = 0.02
    x, y, z = sol.positions.T
    inside = ((np.abs(x) < 0.3 + radius) & (np.abs(y) < 0.3 + radius)
              & (np.abs(z + 0.5) < 0.02 + radius - 1e-9))
    assert not inside.any()


def test_a_rod_whose_rest_shape_runs_into_a_thin_edge_is_not_dropped_through_it():
    # A rod at rest 1 mm above the axis of a knife edge 5 mm thick: deep in
    # a curved obstacle, so the solve would start from the free
    # equilibrium, but that one sags 7 cm clear under the edge, through it:
    # Newton from it would find the rod hanging free below the edge. The
    # rod is pushed up out of the edge and rests on it.
    rho = 0.005
    scene = knife_edge_scene(0.5, 0.6, rho)
    scene["base_position"] = [0.0, 0.0, -rho + 0.001]
    free = softspine.solve({k: v for k, v in scene.items() if k != "obstacles"}, n_elements=20)
    assert free.positions[:, 2].min() < -0.05
    sol = softspine.solve(scene, n_elements=20)
    assert sol.converged and sol.stable, sol.message
    assert len(sol.contacts["force"]) >= 1
    assert sol.contacts["normal"][:, 2].min() > 0.99
    np.testing.assert_allclose(sol.contacts["arc_length"].mean(), 0.6, atol=0.01)


def test_a_target_inside_an_obstacle_is_refused_with_the_reason():
    robot = softspine.Robot({"obstacles": [WALL]})
    ik = robot.inverse([0.2, 0.0, -0.9], load=0.03)
    assert not ik.reached and ik.ending == "out_of_reach"
    assert "inside obstacle 0 (a half_space)" in ik.message
    assert ik.starts == 1
    # The same target without the wall is reached.
    assert softspine.Robot().inverse([0.2, 0.0, -0.9], load=0.03).reached


@pytest.mark.parametrize("target", [[0.13, 0.0, -0.95], [0.13, 0.05, -0.9]])
def test_a_target_on_the_wall_is_reached_leaning_on_it(target):
    robot = softspine.Robot({"obstacles": [WALL]})
    ik = robot.inverse(target, load=0.03)
    assert ik.reached, ik.message
    sol = ik.solution
    assert sol.converged and sol.stable
    assert sol.positions[:, 0].max() <= 0.13 + 1e-9
    # The answer is the forward solve of its own actuation.
    again = robot.forward(ik.rest_curvature, load=0.03)
    np.testing.assert_allclose(again.tip_position, target, atol=1e-9)


def test_a_target_behind_a_ball_is_reached_around_it():
    target = [0.25, 0.0, -0.85]
    free = softspine.Robot().inverse(target, load=0.03)
    # A ball across the free answer's path: 1 cm into its surface (the
    # robot's is 2 cm off its backbone).
    centre = free.solution.positions[12] + [0.06, 0.0, 0.0]
    ball = {"shape": "sphere", "centre": centre.tolist(), "radius": 0.05}
    assert np.linalg.norm(free.solution.positions - centre, axis=1).min() < 0.07 - 0.01
    ik = softspine.Robot({"obstacles": [ball]}).inverse(target, load=0.03)
    assert ik.reached, ik.message
    sol = ik.solution
    assert sol.converged and sol.stable
    # No chord passes within the robot's radius of the ball.
    p = sol.positions
    chord = p[1:] - p[:-1]
    t = np.clip(np.einsum("ij,ij->i", centre - p[:-1], chord)
                / np.einsum("ij,ij->i", chord, chord), 0.0, 1.0)
    distance = np.linalg.norm(p[:-1] + t[:, None] * chord - centre, axis=1)
    assert distance.min() >= 0.07 - 1e-9


def knife_edge_scene(load: float, edge: float = 0.6, rho: float = 1e-6) -> dict:
    """A weightless cantilever along +x with a downward tip force, resting
    on a knife edge across it at x = edge (a thin capsule under the rod)."""
    return {
        "length": 1.0,
        "stiffness": {"kx": 1.0, "ky": 1.0, "kz": 1.0},
        "base_quaternion": ALONG_X,
        "tip_force": [0.0, 0.0, -load],
        "obstacles": [{"shape": "capsule", "a": [edge, -1.0, -rho], "b": [edge, 1.0, -rho],
                       "radius": rho}],
    }


def test_a_cantilever_on_a_knife_edge_meets_the_propped_cantilever():
    # Small deflection: the edge carries R = P (3 L - a) / (2 a); the edge
    # on a node, the force converges at second order.
    load, edge = 1e-3, 0.6
    errors = []
    for n in (20, 40, 80):
        sol = softspine.solve(knife_edge_scene(load, edge), n_elements=n)
        assert sol.converged and sol.stable, sol.message
        force = sol.contacts["force"].sum()
        errors.append(abs(force / (load * (3.0 - edge) / (2.0 * edge)) - 1.0))
        np.testing.assert_allclose(sol.contacts["arc_length"], edge, atol=1e-9)
    assert errors[-1] < 1e-4
    assert errors[0] / errors[1] > 3.5 and errors[1] / errors[2] > 3.5, errors


def test_a_cantilever_sliding_over_a_knife_edge_meets_the_shooting_reference():
    # Large deflection: the rod slides over the edge, which touches it
    # inside an element; the reaction (normal to the rod) against shooting.
    from contact_reference import knife_edge
    load = 2.0
    reaction, s_contact, tip_x, tip_z = knife_edge(1.0, load, 1.0, 0.6)
    assert s_contact > 0.6
    errors = []
    for n in (20, 40, 80, 160):
        sol = softspine.solve(knife_edge_scene(load), n_elements=n)
        assert sol.converged and sol.stable, sol.message
        assert len(sol.contacts["force"]) == 1
        errors.append(abs(sol.contacts["force"][0] - reaction) / reaction)
        assert abs(sol.contacts["arc_length"][0] - s_contact) < 30.0 / n**2
        assert np.hypot(sol.tip_position[0] - tip_x, sol.tip_position[2] - tip_z) < 0.5 / n**2
        # The edge pushes across the chord it touches.
        k = int(np.ceil(sol.contacts["arc_length"][0] * n))
        chord = sol.positions[k] - sol.positions[k - 1]
        assert abs(np.dot(sol.contacts["normal"][0], chord)) < 1e-9 * np.linalg.norm(chord)
    # A kink inside an element: the force converges at first order or
    # better (measured ratios 2.4 to 2.6 a halving), the tip at second.
    assert errors[-1] < 5e-4
    assert all(a / b > 2.0 for a, b in zip(errors, errors[1:], strict=False)), errors


def catmull_rom(points: np.ndarray, samples: int = 400) -> np.ndarray:
    """Points along the Catmull-Rom spline through `points` (one-sided end
    tangents), as the lumen's centreline is defined."""
    n = len(points) - 1
    tangents = np.vstack([points[1] - points[0], 0.5 * (points[2:] - points[:-2]),
                          points[-1] - points[-2]])
    out = []
    for i in range(n):
        u = np.linspace(0.0, 1.0, samples, endpoint=False)[:, None]
        out.append((2 * u**3 - 3 * u**2 + 1) * points[i] + (u**3 - 2 * u**2 + u) * tangents[i]
                   + (-2 * u**3 + 3 * u**2) * points[i + 1] + (u**3 - u**2) * tangents[i + 1])
    return np.vstack(out + [points[-1:]])


def test_a_rod_pushed_into_a_bent_vessel_stays_inside_it():
    # A 1 mm rod inserted step by step (warm starts) into an 8 mm vessel that
    # bends by 90 degrees at a radius of 80 mm: it touches the outer wall with
    # its tip and the inner one on its way, each step in a few Newton steps,
    # and no node leaves the vessel (its wall 0.5 mm off the backbone).
    bend = 0.08
    angles = np.linspace(0.0, np.pi / 2, 13)[1:]
    points = np.vstack([[[-0.02, 0, 0], [0.05, 0, 0]],
                        np.c_[0.05 + bend * np.sin(angles), bend * (1 - np.cos(angles)),
                              0 * angles],
                        [[0.05 + bend, bend + 0.1, 0]]])
    vessel = {"shape": "lumen", "centreline": points.tolist(), "radius": 0.004}
    centreline = catmull_rom(points)
    q = None
    for n in range(20, 37, 2):
        scene = {"length": 0.005 * n, "stiffness": {"E": 50e9, "G": 19e9, "diameter": 0.001},
                 "base_quaternion": ALONG_X, "obstacles": [vessel]}
        start = None if q is None else np.vstack([q, np.repeat(q[-1:], n + 1 - len(q), 0)])
        sol = softspine.solve(scene, n_elements=n, initial=start)
        assert sol.converged and sol.stable, (n, sol.message)
        assert sol.iterations <= 6, (n, sol.iterations)
        assert len(sol.contacts["force"]) >= 2
        q = sol.quaternions
        distance = np.linalg.norm(sol.positions[:, None, :] - centreline[None], axis=2).min(1)
        assert distance.max() <= 0.004 - 0.0005 + 1e-7, (n, distance.max())


@pytest.mark.parametrize(("length", "inner"), [(0.06, False), (0.12, True)])
def test_a_rod_pushed_into_a_curved_tube_meets_the_shooting_reference(length, inner):
    # A 1 mm steel rod clamped on the axis of an 8 mm tube where it starts
    # to bend (radius 80 mm, half a turn): pushed in 60 mm its tip rides the
    # outer wall; 120 mm, a point of it also rides the inner wall. Against
    # shooting with the contacts' arc lengths and forces unknowns
    # (tests/contact_reference.rod_in_bend). The tube is a lumen through
    # points 2 mm apart on the circle (its spline is off the circle by 7e-10 m
    # at most inside the bend).
    # Shape and tip force at second order; the inner contact, inside an
    # element, its force at first order or better (the shear's kink).
    E, diameter, bend, radius = 50e9, 0.001, 0.08, 0.004
    ei = E * math.pi * diameter**4 / 64.0
    step = bend * (math.pi / 2) / 64
    turn = np.linspace(0.0, math.pi, 129)
    centreline = np.vstack([np.c_[np.arange(-6, 0) * step, np.zeros((6, 2))],
                            np.c_[bend * np.sin(turn), bend * (1 - np.cos(turn)), 0 * turn],
                            np.c_[-np.arange(1, 7) * step, np.full(6, 2 * bend), np.zeros(6)]])
    scene = {"length": length, "stiffness": {"E": E, "G": E / 2.6, "diameter": diameter},
             "base_quaternion": ALONG_X,
             "obstacles": [{"shape": "lumen", "centreline": centreline, "radius": radius}]}
    ref = rod_in_bend(ei, length, bend, radius - diameter / 2, inner)
    shape_errors, tip_errors, inner_errors = [], [], []
    for n in (20, 40, 80, 160):
        sol = softspine.solve(scene, n_elements=n)
        assert sol.converged and sol.stable, sol.message
        contacts = sol.contacts
        assert len(contacts["force"]) == len(ref["contacts"]), contacts
        assert (contacts["force"] > 0).all()
        shape_errors.append(np.abs(sol.positions[:, :2]
                                   - ref["path"](np.linspace(0.0, length, n + 1))).max())
        tip_errors.append(abs(contacts["force"][-1] - ref["contacts"][-1][1]))
        assert contacts["arc_length"][-1] == pytest.approx(length)
        if inner:
            s_ref, force_ref, _ = ref["contacts"][0]
            assert abs(contacts["arc_length"][0] - s_ref) <= length / n
            inner_errors.append(abs(contacts["force"][0] - force_ref))
    assert shape_errors[-1] < 1e-6 and tip_errors[-1] < 5e-4 * ref["contacts"][-1][1]
    for errors in (shape_errors, tip_errors) if not inner else (shape_errors,):
        ratios = np.array(errors[:-1]) / np.array(errors[1:])
        assert (ratios > 3.3).all(), errors
    if inner:
        assert (np.diff(inner_errors) < 0).all(), inner_errors
        assert inner_errors[-1] < 5e-3 * ref["contacts"][0][1]


def test_a_catheter_advanced_through_a_3d_vessel_converges_at_every_step():
    # examples/catheter.py's vessel at one radius, 4.5 mm: the 1.5 mm
    # catheter pushed from 40 to 150 mm, 5 mm a step, each step started
    # from the last shape with its tip bending on. At 140 and 145 mm the
    # QP's contact set cycled until the line search gave up; now a refused
    # step is retried with the held set the iteration began with.
    centreline = [[-0.02, 0.0, 0.0], [0.03, 0.0, 0.0], [0.07, 0.012, 0.0], [0.095, 0.045, 0.0],
                  [0.105, 0.09, 0.01], [0.1, 0.13, 0.04], [0.09, 0.16, 0.08]]
    catheter = {"stiffness": {"E": 0.5e9, "G": 0.5e9 / 2.8, "diameter": 0.0015},
                "base_quaternion": ALONG_X,
                "obstacles": [{"shape": "lumen", "centreline": centreline, "radius": 0.0045}]}
    q = None
    for n in range(8, 31):
        start = None
        if q is not None:
            turn = quaternion_product(q[-2] * [1.0, -1.0, -1.0, -1.0], q[-1])
            start = np.vstack([q, quaternion_product(q[-1], turn)])
        sol = softspine.solve({**catheter, "length": 0.005 * n}, n_elements=n, initial=start)
        assert sol.converged and sol.stable, (0.005 * n, sol.message)
        q = sol.quaternions


def quaternion_product(a, b) -> np.ndarray:
    """The Hamilton product of quaternions [w, x, y, z] (each component may
    be an array)."""
    w1, x1, y1, z1 = a
    w2, x2, y2, z2 = b
    return np.array([w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2, w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
                     w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2, w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2])


def test_a_robots_sensitivity_in_contact_holds_the_contact():
    # Pressed on the wall with its tip, the robot's sensitivities to its
    # sections' curvature keep the tip on the wall (dx = 0) and match
    # differences of the forward solve (the contact held throughout).
    robot = softspine.Robot({"obstacles": [WALL]})
    bend = np.zeros((10, 2))
    bend[:, 1] = 0.6
    sensitivity = robot.sensitivity(bend, load=0.03)
    assert np.abs(sensitivity.tip_position[0]).max() < 1e-12
    for j in (1, 3, 19):
        step = 1e-6
        plus, minus = bend.copy(), bend.copy()
        plus.flat[j] += step
        minus.flat[j] -= step
        difference = (robot.forward(plus, load=0.03).tip_position
                      - robot.forward(minus, load=0.03).tip_position) / (2 * step)
        np.testing.assert_allclose(sensitivity.tip_position[:, j], difference, atol=1e-8)


# Triangle meshes (anatomy, fixtures): the signed distance of parry3d's tree
# against the shapes it triangulates exactly, read from STL and OBJ files.
def box_mesh(lower, upper) -> tuple[np.ndarray, np.ndarray]:
    """A box's surface as 12 triangles wound outwards (corner i has bit 0
    for x, 1 for y, 2 for z at the upper side)."""
    lower, upper = np.asarray(lower, float), np.asarray(upper, float)
    corners = np.array([[(upper if i >> k & 1 else lower)[k] for k in range(3)]
                        for i in range(8)])
    faces = [[0, 2, 3, 1], [4, 5, 7, 6], [0, 1, 5, 4], [2, 6, 7, 3], [0, 4, 6, 2],
             [1, 3, 7, 5]]
    triangles = [t for f in faces for t in ([f[0], f[1], f[2]], [f[0], f[2], f[3]])]
    return corners, np.array(triangles)


def write_binary_stl(path, vertices, triangles) -> None:
    record = np.dtype([("normal", "<f4", 3), ("corners", "<f4", (3, 3)), ("extra", "<u2")])
    data = np.zeros(len(triangles), record)
    data["corners"] = vertices[triangles]
    with open(path, "wb") as f:
        f.write(b"solid made by the tests".ljust(80))
        f.write(np.uint32(len(triangles)).tobytes())
        f.write(data.tobytes())


def write_obj(path, vertices, triangles) -> None:
    lines = [f"v {float(x)!r} {float(y)!r} {float(z)!r}" for x, y, z in vertices]
    lines += ["f " + " ".join(str(i + 1) for i in t) for t in triangles]
    path.write_text("\n".join(lines) + "\n")


TETRAHEDRON = {"shape": "mesh", "vertices": [[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]],
               "triangles": [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]]}
TETRAHEDRON_AT_DEPTH = {**TETRAHEDRON, "scale": 0.1, "position": [0.5, 0.0, -0.3]}


def test_a_floor_read_from_an_stl_file_in_millimetres_is_the_table(tmp_path):
    # The slab's top face is z = 0 exactly: the lifted rod lies on it as on
    # the half-space, node for node; the file given as a Path.
    vertices, triangles = box_mesh([-1000.0, -1000.0, -200.0], [3000.0, 1000.0, 0.0])
    write_binary_stl(tmp_path / "slab.stl", vertices, triangles)
    slab = {"shape": "mesh", "file": tmp_path / "slab.stl", "scale": 0.001}
    table = softspine.solve(heavy_rod(2.0, base_position=[0, 0, 0.006], radius=0.005),
                            n_elements=40)
    mesh = softspine.solve(heavy_rod(2.0, base_position=[0, 0, 0.006], radius=0.005,
                                     obstacles=[slab]), n_elements=40)
    assert mesh.converged and mesh.stable, mesh.message
    np.testing.assert_allclose(mesh.positions, table.positions, rtol=0, atol=1e-12)
    np.testing.assert_allclose(mesh.contacts["force"], table.contacts["force"], rtol=1e-9)


def test_a_rod_on_a_tilted_box_mesh_is_the_rod_on_the_box():
    # A box turned 45 degrees about y shows the rod an edge across its path;
    # the mesh (placed by position and orientation) and the box shape have
    # the same signed distance, so the same equilibrium. The rod has a
    # radius: its surface rounds the edge (a backbone of no radius across a
    # sharp edge has no unique normal at the contact).
    turn = [math.cos(math.pi / 8), 0.0, math.sin(math.pi / 8), 0.0]
    half = np.array([0.05, 0.2, 0.05])
    centre = [0.5, 0.0, -0.02 - 0.05 * math.sqrt(2.0)]
    box = {"shape": "box", "centre": centre, "half_extents": half.tolist(),
           "orientation": turn}
    vertices, triangles = box_mesh(-half, half)
    mesh = {"shape": "mesh", "vertices": vertices, "triangles": triangles,
            "position": centre, "orientation": turn}
    on_box = softspine.solve(heavy_rod(1.0, obstacles=[box], radius=0.005), n_elements=20)
    on_mesh = softspine.solve(heavy_rod(1.0, obstacles=[mesh], radius=0.005), n_elements=20)
    assert on_mesh.converged and on_mesh.stable, on_mesh.message
    assert len(on_mesh.contacts["force"]) == 1 and on_mesh.contacts["force"][0] > 0.0
    np.testing.assert_allclose(on_mesh.positions, on_box.positions, rtol=0, atol=1e-10)
    for key in ("arc_length", "point", "normal", "force"):
        np.testing.assert_allclose(on_mesh.contacts[key], on_box.contacts[key], rtol=1e-8,
                                   atol=1e-10)


def test_a_rod_inside_a_tube_mesh_lies_as_in_the_lumen():
    # A closed 64-sided prism, free inside, with a face at the bottom: near
    # the bottom its gap is that of a round lumen of the inscribed radius,
    # so the sagging rod rests on it the same way.
    sides, radius = 64, 0.01
    angles = -np.pi / 2 + np.pi / sides + 2 * np.pi * np.arange(sides) / sides
    ring = np.c_[0 * angles, radius * np.cos(angles), radius * np.sin(angles)]
    vertices = np.vstack([ring + [-0.05, 0, 0], ring + [0.5, 0, 0]])
    sides_ = [[k, (k + 1) % sides, sides + (k + 1) % sides] for k in range(sides)]
    sides_ += [[k, sides + (k + 1) % sides, sides + k] for k in range(sides)]
    caps = [[0, k + 1, k] for k in range(1, sides - 1)]
    caps += [[sides, sides + k, sides + k + 1] for k in range(1, sides - 1)]
    tube = {"shape": "mesh", "vertices": vertices, "triangles": sides_ + caps,
            "free": "inside"}
    assert softspine.read_obstacle(tube)["free"] == "inside"
    lumen = {"shape": "lumen", "centreline": [[-0.05, 0, 0], [0.5, 0, 0]],
             "radius": radius * math.cos(math.pi / sides)}
    scene = {"length": 0.3, "stiffness": {"E": 2e6, "G": 8e5, "diameter": 0.002},
             "gravity": {"linear_density": 0.05, "vector": [0.0, 0.0, -9.81]},
             "base_quaternion": ALONG_X}
    in_lumen = softspine.solve({**scene, "obstacles": [lumen]}, n_elements=30)
    in_mesh = softspine.solve({**scene, "obstacles": [tube]}, n_elements=30)
    assert in_mesh.converged and in_mesh.stable, in_mesh.message
    assert len(in_mesh.contacts["force"]) >= 1
    np.testing.assert_allclose(in_mesh.positions, in_lumen.positions, rtol=0, atol=1e-10)
    np.testing.assert_allclose(in_mesh.contacts["force"], in_lumen.contacts["force"],
                               rtol=1e-7)


def test_a_scene_file_finds_its_mesh_beside_it(tmp_path, monkeypatch):
    vertices, triangles = box_mesh([-1.0, -1.0, -0.2], [3.0, 1.0, 0.0])
    write_obj(tmp_path / "slab.obj", vertices, triangles)
    (tmp_path / "scene.toml").write_text(
        "length = 2.0\nbase_position = [0.0, 0.0, 0.006]\nradius = 0.005\n"
        f"base_quaternion = {ALONG_X}\n"
        "[stiffness]\nkx = 1.0\nky = 1.0\nkz = 1.0\n"
        "[gravity]\nlinear_density = 1.0\nvector = [0.0, 0.0, -1.0]\n"
        "[[obstacles]]\nshape = \"mesh\"\nfile = \"slab.obj\"\n")
    monkeypatch.chdir("/")
    sol = softspine.solve(tmp_path / "scene.toml", n_elements=20)
    table = softspine.solve(heavy_rod(2.0, base_position=[0, 0, 0.006], radius=0.005),
                            n_elements=20)
    np.testing.assert_allclose(sol.positions, table.positions, rtol=0, atol=1e-12)


@pytest.mark.parametrize("shape", [
    {"shape": "box", "centre": [0.5, 0, -0.2], "half_extents": [0.1, 0.1, 0.1]},
    {"shape": "cylinder", "a": [0.5, -0.2, -0.2], "b": [0.5, 0.2, -0.2], "radius": 0.1},
    TETRAHEDRON_AT_DEPTH,
])
def test_a_rod_of_no_radius_near_sharp_edges_is_warned(shape):
    # Where a backbone of no radius meets an edge its contact normal is not
    # unique (and the solve may fail): the scene says so, by name, and not
    # once the rod has a radius.
    with pytest.warns(UserWarning, match=r"obstacles\[0\] \(\w+\) has sharp edges.*radius"):
        softspine.Scene(heavy_rod(1.0, obstacles=[shape]))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        softspine.Scene(heavy_rod(1.0, obstacles=[shape], radius=0.002))
        softspine.Scene(heavy_rod(1.0, obstacles=[{"shape": "sphere", "centre": [0.5, 0, -0.2],
                                                    "radius": 0.1}]))




@pytest.mark.parametrize(("change", "field", "reason"), [
    ({"triangles": [[0, 1, 2], [0, 3, 1], [0, 2, 3], [1, 3, 2]]}, "triangles",
     "wound inwards"),
    ({"triangles": [[0, 1, 4]]}, "triangles", "names a vertex past"),
    ({"vertices": [[0, 0, 0], [1, 0, 0], [2, 0, 0], [3, 0, 0]]}, "triangles",
     "no triangle of non-zero area"),
    ({"free": "nowhere"}, "free", "inside"),
    ({"file": "no-such-mesh.stl"}, "file", "not both"),
])
def test_bad_meshes_are_refused_by_name(change, field, reason):
    mesh = {**TETRAHEDRON, **change}
    with pytest.raises(ValueError, match=rf"^obstacle\.{field}: .*{reason}"):
        softspine.read_obstacle(mesh)
    with pytest.raises(ValueError, match=rf"obstacles\[0\]\.{field}: .*{reason}"):
        softspine.solve(heavy_rod(1.0, obstacles=[mesh]), n_elements=10)


def test_a_missing_mesh_file_is_refused_with_its_path(tmp_path):
    with pytest.raises(ValueError, match=r"obstacles\[0\]\.file.*nothing\.stl.*cannot be read"):
        softspine.solve(heavy_rod(1.0, obstacles=[{"shape": "mesh",
                                                   "file": str(tmp_path / "nothing.stl")}]),
                        n_elements=10)


def test_a_mesh_is_plotted_from_its_file(tmp_path):
    figure = pytest.importorskip("matplotlib.figure")
    from softspine.plotting import plot_obstacles

    vertices, triangles = box_mesh([0.0, 0.0, 0.0], [1.0, 2.0, 3.0])
    write_binary_stl(tmp_path / "box.stl", vertices, triangles)
    ax = figure.Figure().add_subplot(projection="3d")
    plot_obstacles([{"shape": "mesh", "file": str(tmp_path / "box.stl")}], ax)
    assert len(ax.collections) == 1


@pytest.mark.parametrize("span", [0.99, 0.9, 0.7])
def test_a_column_pushed_along_its_line_buckles_as_the_clamped_pinned_elastica(span):
    # A straight rod whose pinned tip is pushed towards its base along its
    # own line must buckle, and no step from the straight rod finds how (the
    # tip's motion along the line is second order in the bending): the held
    # leg starts from a small bump, in the softer plane (kx < ky: y). Not
    # converged before (the iteration limit). The pin's force and the shape
    # against shooting with (m0, n) as unknowns, at second order, on the
    # side of the line the rod took (mirror equilibria; the bump is no
    # equilibrium and the first step may end on either).
    ref = clamped_pinned(1.0, 1.0, span)
    scene = {"length": 1.0, "stiffness": {"kx": 1.0, "ky": 100.0, "kz": 1.0},
             "base_quaternion": ALONG_X, "tip": {"type": "pinned", "position": [span, 0.0, 0.0]}}
    force_errors, shape_errors = [], []
    for n in (20, 40, 80):
        sol = softspine.solve(scene, n_elements=n)
        assert sol.converged and sol.stable, sol.message
        s = np.linspace(0.0, 1.0, n + 1)
        side = np.sign(sol.positions[n // 2, 1])
        assert side != 0.0
        force = sol.tip_reaction_force[:2] * [1.0, side]
        force_errors.append(np.abs(force - ref["force"]).max())
        shape_errors.append(np.abs(side * sol.positions[:, 1] - ref["y"](s)).max())
        assert np.abs(sol.positions[:, 2]).max() < 1e-12
    assert force_errors[-1] < 1e-3 * np.linalg.norm(ref["force"]) and shape_errors[-1] < 1e-4
    for errors in (force_errors, shape_errors):
        assert errors[0] / errors[1] > 3.5 and errors[1] / errors[2] > 3.5, errors


@pytest.mark.parametrize("span", [0.99, 0.9])
def test_a_heavy_rod_pushed_along_a_floor_snakes_along_it(span):
    # A heavy isotropic rod lying on a frictionless floor, its tip pinned on
    # the floor nearer the base: it buckles sideways along the floor (no
    # work against its weight; an arch standing up would fall over). Not
    # converged before: the released leg's residual counted the held tip's
    # miss left in the workspace by the direct attempt, the pinned tip's
    # contact row repeated its held row (a singular system), and nothing
    # bent the straight rod.
    floor = {"shape": "half_space", "point": [0, 0, 0], "normal": [0, 0, 1]}
    scene = {"length": 1.0, "stiffness": {"kx": 1.0, "ky": 1.0, "kz": 1.0},
             "base_quaternion": ALONG_X, "obstacles": [floor],
             "gravity": {"linear_density": 1.0, "vector": [0, 0, -9.81]},
             "tip": {"type": "pinned", "position": [span, 0.0, 0.0]}}
    for n in (20, 40):
        sol = softspine.solve(scene, n_elements=n)
        assert sol.converged and sol.stable, sol.message
        np.testing.assert_allclose(sol.tip_position, [span, 0.0, 0.0], atol=1e-12)
        assert np.abs(sol.positions[:, 2]).max() < 1e-9
        assert np.abs(sol.positions[:, 1]).max() > 0.01
        # The floor and the pin carry the weight but the base's half element
        # (the clamp's).
        total = sol.contacts["force"].sum() + sol.tip_reaction_force[2]
        assert total == pytest.approx(9.81 * (1.0 - 0.5 / n), rel=1e-9)


def test_a_rod_sagging_onto_a_floor_and_pushed_along_it_snakes_out_of_its_plane():
    # The base 1 mm above the floor: the loaded rod sags onto it, so its
    # stretch is no straight line but lies in a plane with the pin's target
    # and its weight. No step leaves that plane, and in it the rod can only
    # arch up off the floor: not converged before (iteration limit). The held
    # leg is tried again from a bump out of the plane, and the rod snakes
    # along the floor as one lying on it does (the same push of the pin, the
    # ends lifted off near the base and the pin).
    lying = {"length": 1.0, "stiffness": {"kx": 1.0, "ky": 1.0, "kz": 1.0},
             "base_quaternion": ALONG_X,
             "gravity": {"linear_density": 1.0, "vector": [0, 0, -9.81]},
             "tip": {"type": "pinned", "position": [0.95, 0.0, 0.0]}}
    for n in (20, 40):
        on = softspine.solve({**lying, "obstacles": [
            {"shape": "half_space", "point": [0, 0, 0], "normal": [0, 0, 1]}]}, n_elements=n)
        above = softspine.solve({**lying, "obstacles": [
            {"shape": "half_space", "point": [0, 0, -0.001], "normal": [0, 0, 1]}]}, n_elements=n)
        assert on.converged and above.converged and above.stable, above.message
        assert above.positions[:, 2].min() > -0.001 - 1e-9
        assert np.abs(above.positions[:, 1]).max() > 0.1
        push, push_above = (abs(s.tip_reaction_force[0]) for s in (on, above))
        assert abs(push_above / push - 1.0) < 1e-3, (push, push_above)


def test_a_held_point_inside_an_obstacle_is_refused_by_name():
    # No contact acts at a held node (its reaction carries the obstacle's
    # push): a pinned tip or guide inside an obstacle would hold the rod
    # through it, and converged silently once held nodes left the contacts.
    floor = {"shape": "half_space", "point": [0, 0, 0], "normal": [0, 0, 1]}
    scene = {"length": 1.0, "stiffness": {"kx": 1.0, "ky": 1.0, "kz": 1.0},
             "base_quaternion": ALONG_X, "obstacles": [floor],
             "tip": {"type": "pinned", "position": [0.9, 0.0, -0.01]}}
    with pytest.raises(ValueError, match=r"^tip\.position: lies inside obstacles\[0\]"):
        softspine.solve(scene, n_elements=20)
    guided = {**scene, "tip": {"type": "free"},
              "guides": [{"s": 0.5, "position": [0.45, 0.0, -0.001]}]}
    with pytest.raises(ValueError, match=r"^guides\[0\]\.position: lies inside obstacles\[0\]"):
        softspine.solve(guided, n_elements=20)
    # On the surface is fine.
    scene["tip"]["position"] = [0.9, 0.0, 0.0]
    assert softspine.solve(scene, n_elements=20).converged
