"""Sliding ports: a point the backbone passes through and slides through,
without friction or against Coulomb friction (a trocar, a guide tube's
exit), against closed forms and shooting (`contact_reference.through_port`,
`stuck_in_port`, `knife_edge`)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from contact_reference import knife_edge, stuck_in_port, through_port
from friction_reference import check_step_sensitivity

import softspine

ALONG_X = [math.sqrt(0.5), 0.0, math.sqrt(0.5), 0.0]


def port_scene(port: tuple[float, float], tip_load: float = 0.0, weight: float = 0.0,
               tilt: float = 0.0) -> dict:
    """A 1 m cantilever along +x (EI = 1) through a port at `(a, h)` of the
    plane turned by `tilt` about x, with a tip load and its weight [N/m]
    pulling down that plane."""
    up = np.array([0.0, -math.sin(tilt), math.cos(tilt)])
    scene = {
        "length": 1.0,
        "stiffness": {"kx": 1.0, "ky": 1.0, "kz": 1.0},
        "base_quaternion": ALONG_X,
        "tip_force": list(-tip_load * up),
        "ports": [{"position": list(port[0] * np.array([1.0, 0.0, 0.0]) + port[1] * up),
                   "axis": [1.0, 0.0, 0.0]}],
    }
    if weight:
        scene["gravity"] = {"linear_density": weight / 9.81, "vector": list(-9.81 * up)}
    return scene, up


@pytest.mark.parametrize("load", [1e-3, -1e-3])
def test_a_cantilever_through_a_port_is_the_propped_cantilever_either_way(load):
    # Small deflection: the port on the rod's line carries R = P (3 L - a)
    # / (2 a) across it, pushed up or pulled down (it holds both ways); the
    # port on a node, second order.
    edge = 0.6
    exact = load * (3.0 - edge) / (2.0 * edge)
    errors = []
    for n in (20, 40, 80):
        sol = softspine.solve(port_scene((edge, 0.0), load)[0], n_elements=n)
        assert sol.converged and sol.stable, sol.message
        force = sol.ports["force"][0]
        assert abs(force[1]) < 1e-15
        errors.append(abs(force[2] / exact - 1.0))
        np.testing.assert_allclose(sol.ports["arc_length"], edge, atol=1e-9)
        np.testing.assert_allclose(sol.ports["point"][0], [edge, 0.0, 0.0], atol=1e-12)
    assert errors[-1] < 1e-4
    assert errors[0] / errors[1] > 3.5 and errors[1] / errors[2] > 3.5, errors


@pytest.mark.parametrize("case", [
    ((0.5, 0.1), 0.0, 0.0, 0.0),
    ((0.5, 0.1), 1.0, 2.0, 0.7),
    ((0.7, -0.2), 0.5, 3.0, -1.2),
])
def test_a_rod_bent_through_a_port_meets_shooting(case):
    # Large deflection: the port off the rod's line, a tip load and the
    # weight, in a plane turned about x (the solver works in 3D). The arc
    # length through the port and the tip converge at second order; the
    # port's force, across a chord that crosses inside an element, at
    # first order (measured 0.3 to 2 h |F|, with the crossing's place).
    port, tip_load, weight, tilt = case
    ref = through_port(1.0, 1.0, port, tip_load, weight)
    size = np.linalg.norm(ref["force"])
    tips, arcs = [], []
    for n in (20, 40, 80, 160):
        scene, up = port_scene(port, tip_load, weight, tilt)
        sol = softspine.solve(scene, n_elements=n)
        assert sol.converged and sol.stable, sol.message
        tip, force = sol.tip_position, sol.ports["force"][0]
        tips.append(np.hypot(tip[0] - ref["tip"][0], tip @ up - ref["tip"][1]))
        arcs.append(abs(sol.ports["arc_length"][0] - ref["arc_length"]))
        in_plane = np.array([force[0], force @ up])
        assert np.linalg.norm(in_plane - ref["force"]) < 2.5 * size / n
        # Nothing out of the plane, and the port on its point.
        assert abs(force @ np.cross([1.0, 0.0, 0.0], up)) < 1e-9 * size
        np.testing.assert_allclose(sol.ports["point"][0],
                                   scene["ports"][0]["position"], atol=1e-10)
        # Frictionless: the force is across the chord it acts on.
        k = int(np.ceil(sol.ports["arc_length"][0] * n))
        chord = sol.positions[k] - sol.positions[k - 1]
        assert abs(force @ chord) < 1e-9 * size * np.linalg.norm(chord)
    assert all(a / b > 2.8 for a, b in zip(arcs, arcs[1:], strict=False)), arcs
    assert tips[-1] < 3e-5 and tips[0] / tips[-1] > 40, tips


def test_a_port_pressed_from_one_side_is_a_knife_edge():
    # Where the load presses the rod onto it, a port holds like a knife
    # edge: the same equilibrium from the contact's unilateral rows (the
    # edge a capsule of radius 1e-6 m, so to about that).
    from test_contact import knife_edge_scene
    load = 2.0
    reaction, s_contact, tip_x, tip_z = knife_edge(1.0, load, 1.0, 0.6)
    for n in (40, 80):
        port = softspine.solve(port_scene((0.6, 0.0), load)[0], n_elements=n)
        edge = softspine.solve(knife_edge_scene(load), n_elements=n)
        assert port.converged and edge.converged
        np.testing.assert_allclose(port.positions, edge.positions, atol=2e-6)
        np.testing.assert_allclose(np.linalg.norm(port.ports["force"][0]),
                                   edge.contacts["force"].sum(), rtol=1e-5)
        assert abs(port.ports["arc_length"][0] - s_contact) < 30.0 / n**2
        assert np.hypot(port.tip_position[0] - tip_x, port.tip_position[2] - tip_z) < 0.5 / n**2


def test_a_port_and_an_obstacle_together():
    # A steel rod through a port, sagging onto a floor beyond it: both
    # kinds of rows in one KKT system. The floor holds the rod's surface
    # above it, the port its backbone, and the forces converge with n.
    scene = {
        "length": 1.0,
        "stiffness": {"E": 200e9, "G": 80e9, "diameter": 0.002},
        "base_quaternion": ALONG_X,
        "gravity": {"linear_density": 0.025, "vector": [0.0, 0.0, -9.81]},
        "ports": [{"position": [0.2, 0.0, 0.0]}],
        "obstacles": [{"shape": "half_space", "point": [0.0, 0.0, -0.05],
                       "normal": [0.0, 0.0, 1.0]}],
    }
    forces = []
    for n in (40, 80, 160):
        sol = softspine.solve(scene, n_elements=n)
        assert sol.converged and sol.stable, sol.message
        assert len(sol.contacts["force"]) > 0 and sol.contacts["force"].min() >= 0.0
        assert sol.positions[:, 2].min() >= -0.05 + 0.001 - 1e-9
        np.testing.assert_allclose(sol.ports["point"][0], [0.2, 0.0, 0.0], atol=1e-10)
        forces.append([sol.contacts["force"].sum(), sol.ports["force"][0][2]])
    forces = np.array(forces)
    changes = np.abs(np.diff(forces, axis=0)).max(axis=1)
    assert changes[1] < 0.5 * changes[0] and changes[1] < 1e-2 * np.abs(forces).max(), forces


def test_ports_come_back_from_dict_and_pickle():
    import pickle
    sol = softspine.solve(port_scene((0.5, 0.1), 1.0)[0], n_elements=20)
    for back in (softspine.Solution.from_dict(sol.to_dict()), pickle.loads(pickle.dumps(sol))):
        for key, value in sol.ports.items():
            np.testing.assert_array_equal(back.ports[key], value)
    assert softspine.solve(port_scene((0.5, 0.0))[0]).ports["port"].tolist() == [0]
    assert softspine.solve({"length": 1.0, "stiffness": {"kx": 1, "ky": 1, "kz": 1}}
                           ).ports["port"].size == 0
    scene = softspine.Scene(port_scene((0.5, 0.1))[0])
    assert softspine.Scene(scene.to_dict()).to_dict()["ports"] == scene.to_dict()["ports"]


@pytest.mark.parametrize("port, key, reason", [
    ({"position": [0.5, 0.0, 0.0], "axis": [0.0, 0.0, 0.0]}, "ports[0].axis", "zero"),
    ({"position": [0.5, 0.0, float("nan")]}, "ports[0].position", "finite"),
    ({"position": [0.5, 0.0, 0.0], "radius": 1.0}, "ports[0]", "radius"),
    ({"position": [0.5, 0.0, 0.0], "friction": -0.1}, "ports[0].friction", ">= 0"),
    ({"position": [0.5, 0.0, 0.0], "friction": float("nan")}, "ports[0].friction", "finite"),
    ({"axis": [1.0, 0.0, 0.0]}, "ports[0]", "position"),
    # Behind the base, and past the tip: the rod never crosses its plane.
    ({"position": [-0.5, 0.0, 0.0]}, "ports[0]", "does not pass"),
    ({"position": [1.5, 0.0, 0.0]}, "ports[0]", "does not pass"),
])
def test_a_bad_port_is_refused_naming_it(port, key, reason):
    scene = port_scene((0.5, 0.0))[0]
    scene["ports"] = [port]
    with pytest.raises(ValueError, match=r"ports\[0\]") as error:
        softspine.solve(scene)
    assert key in str(error.value) and reason in str(error.value)


@pytest.mark.parametrize("options, name", [
    ({"method": "lm"}, "method"),
    ({"scheme": "fe4"}, "scheme"),
    ({"method": "shooting"}, "method"),
])
def test_a_port_is_solved_by_newton_on_fd2_and_says_so(options, name):
    with pytest.raises(ValueError, match=name):
        softspine.solve(port_scene((0.5, 0.1))[0], **options)


def test_the_tip_sensitivity_through_a_port_is_the_finite_difference():
    # Along the port (the rod keeps sliding through it): the implicit
    # function theorem on the KKT system against central differences.
    scene = port_scene((0.5, 0.1), 0.5, 1.0)[0]
    solver = softspine.Solver(scene, n_elements=40)
    assert solver.solve().converged
    sensitivity = solver.sensitivity("tip_force[2]")
    step = 1e-5
    tips = []
    for sign in (1.0, -1.0):
        moved = dict(scene, tip_force=[0.0, 0.0, scene["tip_force"][2] + sign * step])
        sol = softspine.solve(moved, n_elements=40, residual_tol=1e-13)
        assert sol.converged
        tips.append(sol.tip_position)
    difference = (tips[0] - tips[1]) / (2.0 * step)
    np.testing.assert_allclose(sensitivity.tip_position[:, 0], difference, atol=1e-9)


def inserted_robot(n: int = 20, **fields) -> softspine.Robot:
    """The seed's robot, weightless, hanging through a port 0.3 m below its base."""
    return softspine.Robot({"gravity": [0, 0, 0], "ports": [{"position": [0, 0, -0.3]}],
                            "insertion_range": [0.0, 0.2], "n_elements": n, **fields})


@pytest.mark.parametrize("insertion", [0.0, 0.1])
def test_a_robot_bent_through_a_port_meets_the_clamped_pinned_beam(insertion):
    # Small curvature kappa in every section, no weight: between the base
    # and the port (a = 0.3 m - insertion) a clamped-pinned beam with rest
    # curvature, EI (w'' - kappa) = R (a - x), w(a) = 0, so the port pushes
    # back with R = 3 EI kappa / (2 a) and the rod leaves it at the slope
    # kappa a / 4; beyond, free, it curves by kappa. Second order in n.
    kappa, length = 0.01, 1.0
    a = 0.3 - insertion
    tip = kappa * a / 4.0 * (length - a) + kappa * (length - a) ** 2 / 2.0
    forces, tips = [], []
    for n in (20, 40, 80):
        robot = inserted_robot(n)
        ei = robot.forward().to_dict()["stiffness"][0]
        sol = robot.forward(np.tile([kappa, 0.0], (10, 1)), insertion=insertion)
        assert sol.converged and sol.stable, sol.message
        np.testing.assert_allclose(sol.positions[0], [0.0, 0.0, -insertion], atol=1e-15)
        np.testing.assert_allclose(sol.ports["arc_length"], a, atol=1e-6)
        forces.append(abs(-sol.ports["force"][0][1] / (1.5 * ei * kappa / a) - 1.0))
        tips.append(abs(sol.tip_position[1] / tip - 1.0))
    assert forces[-1] < 2e-3 and tips[-1] < 5e-4, (forces, tips)
    assert forces[0] / forces[1] > 3.8 and forces[1] / forces[2] > 3.8, forces
    assert tips[0] / tips[1] > 3.5 and tips[1] / tips[2] > 3.5, tips


def test_a_robots_ports_and_insertion_range_come_back_and_are_checked():
    robot = inserted_robot()
    again = softspine.Robot(robot.to_dict())
    assert again.to_dict()["ports"] == [{"position": [0.0, 0.0, -0.3], "axis": [0.0, 0.0, -1.0]}]
    assert again.to_dict()["insertion_range"] == [0.0, 0.2]
    # The straight robot slides through: only the base moves.
    sol = robot.forward(insertion=0.15)
    np.testing.assert_allclose(sol.tip_position, [0.0, 0.0, -1.15], atol=1e-12)
    np.testing.assert_allclose(sol.ports["force"], 0.0, atol=1e-12)
    for bad, reason in [(0.25, "outside insertion_range"), (float("nan"), "finite")]:
        with pytest.raises(ValueError, match="insertion") as error:
            robot.forward(insertion=bad)
        assert reason in str(error.value)
    for bad in ([0.2, 0.1], [0.0, float("inf")]):
        with pytest.raises(ValueError, match="insertion_range"):
            inserted_robot(insertion_range=bad)


TENDONS = [{"offset": [0.01, 0.0], "section": 10},
           {"offset": [-0.005, 0.0087], "section": 10},
           {"offset": [-0.005, -0.0087], "section": 10}]


@pytest.mark.parametrize("fields", [{}, {"tendons": TENDONS, "max_tension": 100.0}])
@pytest.mark.parametrize("target", [[0.0, 0.0, -1.1], [0.15, 0.05, -1.0], [0.0, 0.1, -1.12]])
def test_the_inverse_kinematics_inserts_the_robot_through_its_port(fields, target):
    # The insertion is one more coordinate: targets past the fixed base's
    # reach are reached by inserting, and the answer is an equilibrium
    # through the port (checked by a forward solve of it).
    robot = softspine.Robot({"ports": [{"position": [0, 0, -0.3]}],
                             "insertion_range": [0.0, 0.2], **fields})
    ik = robot.inverse(target, load=0.03)
    assert ik.reached, ik.message
    assert 0.0 <= ik.insertion <= 0.2 and "insertion" in ik.message
    tensions = ik.tensions if len(ik.tensions) else None
    sol = robot.forward(ik.rest_curvature, load=0.03, tensions=tensions, insertion=ik.insertion)
    assert np.linalg.norm(sol.tip_position - target) < 1e-6
    np.testing.assert_allclose(sol.ports["point"][0], [0.0, 0.0, -0.3], atol=1e-10)
    np.testing.assert_allclose(sol.positions[0], [0.0, 0.0, -ik.insertion], atol=1e-12)
    if target[2] < -1.0 - 1e-9 and np.hypot(target[0], target[1]) < 0.11:
        assert ik.insertion > 0.05


def test_a_target_past_the_insertion_is_out_of_reach_and_says_why():
    robot = softspine.Robot({"ports": [{"position": [0, 0, -0.3]}], "insertion_range": [0.0, 0.2]})
    ik = robot.inverse([0.0, 0.05, -1.25], load=0.03)
    assert not ik.reached and ik.ending == "out_of_reach"
    assert "inserted by 0.2 m" in ik.message and ik.insertion == pytest.approx(0.2)


def test_tracking_through_a_port_keeps_the_insertion_and_the_result_comes_back():
    robot = softspine.Robot({"ports": [{"position": [0, 0, -0.3]}], "insertion_range": [0.0, 0.2]})
    angles = np.linspace(0.0, 2.0 * np.pi, 6)
    circle = [[0.05 * np.cos(t), 0.05 * np.sin(t), -1.05] for t in angles]
    results = robot.track(circle, load=0.03)
    assert all(r.reached for r in results), [r.message for r in results]
    # The circle is symmetric about the axis: one insertion all round (to
    # the least-norm choice's precision).
    insertions = [r.insertion for r in results]
    assert max(insertions) - min(insertions) < 1e-5 and insertions[0] > 0.0
    d = results[1].to_dict()
    assert softspine.IkResult.from_dict(d).insertion == d["insertion"] == results[1].insertion
    del d["insertion"]
    assert softspine.IkResult.from_dict(d).insertion == 0.0


@pytest.mark.slow
def test_a_catheter_fed_through_a_port_converges_at_every_step():
    # examples/catheter.py's vessel, sheath and port: the handle moves the
    # base 5 mm a step from 40 to 150 mm, each solve warm from the last;
    # every step converges with the catheter through the port and inside
    # the vessel. Clamped at the entry and lengthened instead, the same
    # steps failed at 140 and 145 mm before Newton retried refused steps.
    centreline = np.array([[-0.26, 0.0, 0.0], [-0.02, 0.0, 0.0], [0.03, 0.0, 0.0],
                           [0.07, 0.012, 0.0], [0.095, 0.045, 0.0], [0.105, 0.09, 0.01],
                           [0.1, 0.13, 0.04], [0.09, 0.16, 0.08]])
    radius = np.r_[0.005, np.linspace(0.005, 0.0035, len(centreline) - 1)]
    vessel = {"shape": "lumen", "centreline": centreline.tolist(), "radius": radius.tolist()}
    catheter = {"length": 0.25, "stiffness": {"E": 0.5e9, "G": 0.5e9 / 2.8, "diameter": 0.0015},
                "base_quaternion": ALONG_X, "obstacles": [vessel],
                "ports": [{"position": [-0.015, 0.0, 0.0]}]}
    q, touched = None, 0
    for depth in np.arange(0.04, 0.1501, 0.005):
        scene = {**catheter, "base_position": [depth - 0.25, 0.0, 0.0]}
        sol = softspine.solve(scene, n_elements=50, initial=q)
        assert sol.converged and sol.stable, (depth, sol.message)
        np.testing.assert_allclose(sol.ports["point"][0], [-0.015, 0.0, 0.0], atol=1e-9)
        np.testing.assert_allclose(sol.positions[0], [depth - 0.25, 0.0, 0.0], atol=1e-15)
        touched = max(touched, len(sol.contacts["force"]))
        q = sol.quaternions
    assert touched >= 2


def test_an_inverse_batch_reports_each_insertion():
    # A batch's answers carry their insertions: applied, they reach.
    robot = softspine.Robot({"ports": [{"position": [0, 0, -0.3]}], "insertion_range": [0.0, 0.2]})
    targets = np.array([[0.0, 0.0, -1.1], [0.0, 0.1, -1.12], [0.1, 0.0, -0.95]])
    batch = robot.inverse_batch(targets, load=0.03, threads=1)
    assert batch.reached.all() and batch.insertion.shape == (3,)
    answers = zip(targets, batch.rest_curvature, batch.insertion, strict=True)
    for target, kappa, insertion in answers:
        tip = robot.forward(kappa, load=0.03, insertion=insertion).tip_position
        assert np.linalg.norm(tip - target) < 1e-6
    assert batch.insertion[0] == pytest.approx(0.1, abs=1e-9)
    assert robot.forward_batch(np.zeros((2, 10, 2)), threads=1).insertion.tolist() == [0.0, 0.0]


def central_difference(scene: dict, key: str, index: int | None, step: float,
                       n: int = 40) -> np.ndarray:
    """The tip's central difference in `scene[key][index]` (or `scene[key]`)."""
    tips = []
    for sign in (1.0, -1.0):
        moved = {k: (list(v) if isinstance(v, list) else v) for k, v in scene.items()}
        if index is None:
            moved[key] = scene[key] + sign * step
        else:
            moved.setdefault(key, [0.0, 0.0, 0.0])
            moved[key] = list(moved[key])
            moved[key][index] += sign * step
        sol = softspine.solve(moved, n_elements=n, residual_tol=1e-13)
        assert sol.converged
        tips.append(sol.tip_position)
    return (tips[0] - tips[1]) / (2.0 * step)


def test_a_sensitivity_that_moves_the_rod_against_a_port_or_an_edge_is_the_difference():
    # Regression: a differenced parameter in contact (the length, the
    # base's position) raised a panic ("Matrix index out of bounds"): the
    # contacts' multipliers were read as held points' reactions. Its rows
    # now move with the rod (the port's crossing, the edge's gap) and the
    # port's and the edge's forces are in the differences.
    # (The edge inside an element: on a node the discrete rod's kink makes
    # the slide along it one-sided.)
    from test_contact import knife_edge_scene
    edge = knife_edge_scene(0.5, edge=0.613, rho=1e-3)
    for scene in (port_scene((0.5, 0.1), 0.5, 1.0)[0], edge):
        solver = softspine.Solver(scene, n_elements=40)
        assert solver.solve().converged
        names = ["length", "base_position[0]", "base_position[2]"]
        sensitivity = solver.sensitivity(names)
        for column, (key, index) in enumerate([("length", None), ("base_position", 0),
                                               ("base_position", 2)]):
            difference = central_difference(scene, key, index, 1e-6)
            np.testing.assert_allclose(sensitivity.tip_position[:, column], difference,
                                       atol=1e-8, err_msg=key)


def test_a_clamped_tip_in_contact_gives_its_reaction_force_but_not_its_moment():
    # The clamp's moment takes the contacts' forces, which the differences
    # along the state's tangent do not move: not given (None) rather than
    # wrong; the force's column is the reaction's difference.
    scene = {"length": 1.0, "stiffness": {"kx": 1.0, "ky": 1.0, "kz": 1.0},
             "base_quaternion": ALONG_X,
             "tip": {"type": "clamped", "position": [0.97, 0.0, 0.0], "quaternion": ALONG_X},
             "gravity": {"linear_density": 1.0, "vector": [0.0, -20.0, 0.0]},
             "obstacles": [{"shape": "half_space", "point": [0, -0.03, 0], "normal": [0, 1, 0]}]}
    solver = softspine.Solver(scene, n_elements=20)
    sol = solver.solve()
    assert sol.converged and len(sol.contacts["force"]) > 0, sol.message
    sensitivity = solver.sensitivity("length")
    assert sensitivity.tip_reaction_moment is None
    assert sensitivity.tip_reaction_force is not None


def test_a_robots_sensitivity_to_its_insertion_is_the_difference():
    # At an insertion, through the port: the tip's derivative in the
    # insertion against forward solves at insertions a step apart. (The
    # port's crossing inside an element: on a node, the polygon's kink
    # makes the derivative one-sided, 13 % off the difference across it.)
    robot = softspine.Robot({"ports": [{"position": [0, 0, -0.3]}], "insertion_range": [0.0, 0.2]})
    kappa = np.tile([0.3, -0.2], (10, 1))
    sensitivity = robot.sensitivity(kappa, load=0.03, parameters="insertion", insertion=0.113)
    step = 1e-5
    tips = [robot.forward(kappa, load=0.03, insertion=0.113 + sign * step).tip_position
            for sign in (1.0, -1.0)]
    difference = (tips[0] - tips[1]) / (2.0 * step)
    np.testing.assert_allclose(sensitivity.tip_position[:, 0], difference, atol=1e-7)
    # Not the base's own motion: the port holds the rod back.
    assert np.linalg.norm(sensitivity.tip_position[:, 0] - [0.0, 0.0, -1.0]) > 1e-3


def test_a_port_and_its_force_are_plotted():
    figure = pytest.importorskip("matplotlib.figure")
    from softspine.plotting import plot_contacts

    sol = softspine.solve(port_scene((0.5, 0.1), 1.0)[0], n_elements=20)
    ax = figure.Figure().add_subplot(projection="3d")
    plot_contacts(sol, ax)
    # The port's dot and its force's arrow.
    assert len(ax.collections) == 2


def test_a_forward_batch_takes_each_samples_insertion():
    # Each sample's base moved by its insertion, the same as a forward solve.
    robot = softspine.Robot({"ports": [{"position": [0, 0, -0.3]}], "insertion_range": [0.0, 0.2]})
    kappa = np.tile([0.3, -0.2], (3, 10, 1))
    insertion = np.array([0.0, 0.05, 0.15])
    batch = robot.forward_batch(kappa, load=0.03, insertion=insertion, threads=1)
    assert batch.converged.all()
    np.testing.assert_array_equal(batch.insertion, insertion)
    for tip, k, d in zip(batch.tip_positions, kappa, insertion, strict=True):
        np.testing.assert_allclose(tip, robot.forward(k, load=0.03, insertion=d).tip_position,
                                   atol=1e-9)
    with pytest.raises(ValueError, match="insertion"):
        robot.forward_batch(kappa, insertion=[0.0, 0.1, 0.3], threads=1)
    with pytest.raises(ValueError, match="insertion"):
        robot.forward_batch(kappa, insertion=[0.0, 0.1], threads=1)
    # On an executor, in parts: the same answers.
    from concurrent.futures import ThreadPoolExecutor
    with ThreadPoolExecutor(2) as executor:
        parts = robot.forward_batch(kappa, load=0.03, insertion=insertion, executor=executor,
                                    chunk=1, part=1, threads=1)
    np.testing.assert_array_equal(parts.insertion, insertion)
    np.testing.assert_allclose(parts.tip_positions, batch.tip_positions, atol=1e-12)


def test_the_inverse_kinematics_inserts_through_a_port_and_leans_on_a_wall():
    # A port and an obstacle together: the target near the wall is reached
    # with the robot pressed on it, the insertion and the contact both in
    # the Jacobian (the base's sensitivity with the contact held).
    wall = {"shape": "half_space", "point": [0.12, 0, 0], "normal": [-1, 0, 0]}
    robot = softspine.Robot({"ports": [{"position": [0, 0, -0.3]}],
                             "insertion_range": [0.0, 0.2], "obstacles": [wall]})
    ik = robot.inverse([0.1, -0.02, -0.98], load=0.03)
    assert ik.reached, ik.message
    assert len(ik.solution.contacts["force"]) >= 1
    assert ik.solution.positions[:, 0].max() <= 0.12 - robot.to_dict().get("radius", 0.0) + 1e-9
    far = robot.inverse([0.08, 0.05, -1.1], load=0.03)
    assert far.reached and far.insertion > 0.05, far.message


def test_a_workspace_draws_the_insertion_over_its_range():
    robot = softspine.Robot({"ports": [{"position": [0, 0, -0.3]}], "insertion_range": [0.0, 0.2]})
    ws = robot.workspace(12, load=0.03, seed=3, threads=1)
    assert ws.converged.all()
    assert ws.insertion.min() >= 0.0 and ws.insertion.max() <= 0.2 and np.ptp(ws.insertion) > 0.05
    for k, d, tip in zip(ws.actuations[:3], ws.insertion[:3], ws.tip_positions[:3], strict=True):
        np.testing.assert_allclose(robot.forward(k, load=0.03, insertion=d).tip_position, tip,
                                   atol=1e-9)
    # The muscles' draws are those of the robot without an insertion.
    plain = softspine.Robot().workspace(12, load=0.03, seed=3, threads=1)
    np.testing.assert_array_equal(plain.actuations, ws.actuations)


def test_a_magnetic_catheter_with_a_limited_field_is_fed_by_its_stage():
    # The field's ball and the insertion's interval in one step: a target
    # above the catheter's reach is reached by inserting it, within
    # max_field; one past both is refused with the field at its limit or
    # the insertion at its end.
    robot = softspine.Robot.from_file("examples/robots/magnetic_catheter.toml")
    fed = softspine.Robot({**robot.to_dict(), "ports": [{"position": [0.0, 0.0, 0.05]}],
                           "insertion_range": [0.0, 0.04]})
    target = [0.04, 0.02, 0.22]
    assert not robot.inverse(target).reached
    ik = fed.inverse(target)
    assert ik.reached, ik.message
    assert 0.0 < ik.insertion <= 0.04 and np.linalg.norm(ik.field) <= 0.05 + 1e-12
    tip = fed.forward(field=ik.field, insertion=ik.insertion).tip_position
    assert np.linalg.norm(tip - target) < 1e-6
    beyond = fed.inverse([0.0, 0.0, 0.3])
    assert not beyond.reached


def test_a_robots_port_behind_its_base_is_refused_by_name():
    for fields, key in [({"ports": [{"position": [0, 0, 0.1]}]}, r"ports\[0\]"),
                        ({"ports": [{"position": [0, 0, -0.3]}], "insertion_range": [0.0, 0.3]},
                         "insertion_range")]:
        with pytest.raises(ValueError, match=key):
            softspine.Robot(fields)


# Friction in a port: the history is the load path from the rest shape (see
# docs/model.md); the rod slides where its friction would leave the cone.

@pytest.mark.parametrize("mu", [0.1, 2.0])
@pytest.mark.parametrize("case", [
    ((0.5, 0.1), 1.0, 2.0, 0.7),
    ((0.7, -0.2), 0.5, 3.0, -1.2),
])
def test_a_rod_bent_through_a_frictional_port_slides_back_as_shooting(case, mu):
    # The rod bends to pass the port off its line: the arc up to it grows,
    # so the rod slides back through it along the whole path, the port
    # pushing it towards the tip by mu times its force across. The arc
    # length and the tip at second order, the force at first (as without
    # friction: the crossing inside an element).
    port, tip_load, weight, tilt = case
    ref = through_port(1.0, 1.0, port, tip_load, weight, friction=mu, slide=1.0)
    size = np.linalg.norm(ref["force"])
    tips, arcs = [], []
    for n in (20, 40, 80, 160):
        scene, up = port_scene(port, tip_load, weight, tilt)
        scene["ports"][0]["friction"] = mu
        sol = softspine.solve(scene, n_elements=n)
        assert sol.converged and sol.stable, sol.message
        ports = sol.ports
        assert ports["sliding"].tolist() == [True]
        force, friction = ports["force"][0], ports["friction"][0]
        across = np.linalg.norm(force - friction)
        assert abs(np.linalg.norm(friction) - mu * across) < 1e-9 * size
        k = int(np.ceil(ports["arc_length"][0] * n))
        chord = sol.positions[k] - sol.positions[k - 1]
        assert friction @ chord > 0.0  # towards the tip: the rod slid back
        tip = sol.tip_position
        tips.append(np.hypot(tip[0] - ref["tip"][0], tip @ up - ref["tip"][1]))
        arcs.append(abs(ports["arc_length"][0] - ref["arc_length"]))
        in_plane = np.array([force[0], force @ up])
        assert np.linalg.norm(in_plane - ref["force"]) < 2.5 * size / n
    assert all(a / b > 2.8 for a, b in zip(arcs, arcs[1:], strict=False)), arcs
    assert tips[-1] < 5e-5 and tips[0] / tips[-1] > 25, tips


def curled_through_port(curvature: float, s_port: float, tip_load: float, mu: float) -> dict:
    """A 1 m rod (EI = 1) curled up in the x-z plane, through a port at its
    rest point `s_port` along its rest tangent there, loaded down at its tip."""
    point = np.array([np.sin(curvature * s_port), 1.0 - np.cos(curvature * s_port)]) / curvature
    axis = [np.cos(curvature * s_port), 0.0, np.sin(curvature * s_port)]
    return {
        "length": 1.0,
        "stiffness": {"kx": 1.0, "ky": 1.0, "kz": 1.0},
        "base_quaternion": ALONG_X,
        "rest_curvature": [[0.0, -curvature]],
        "tip_force": [0.0, 0.0, -tip_load],
        "ports": [{"position": [point[0], 0.0, point[1]], "axis": axis, "friction": mu}],
    }


def test_a_curled_rod_sticks_in_a_port_with_enough_friction_as_a_held_point():
    # The rod's material in the port is held: against shooting with that
    # point held, every step of whose load path needs a friction of at
    # most `needed` (|along| / |across|, 2.36 to 2.45). With twice that the
    # port holds the material at its rest crossing (the rest polygon's:
    # within h^2 of the arc's); with less the rod slides.
    curvature, s_port, load = 1.0, 0.5, 0.5
    ref = stuck_in_port(1.0, 1.0, curvature, s_port, load)
    needed = max(ref["ratios"])
    # The rest polygon's crossing of the port's plane (at n = 20).
    free = curled_through_port(curvature, s_port, 0.0, 0.0)
    port = free.pop("ports")[0]
    rest = softspine.solve(free, n_elements=20).positions
    along = (rest - port["position"]) @ port["axis"]
    k = int(np.argmax(along >= 0.0))
    rest_arc = (k - along[k] / (along[k] - along[k - 1])) / 20
    tips, forces = [], []
    for n in (20, 40, 80, 160):
        sol = softspine.solve(curled_through_port(curvature, s_port, load, 2.0 * needed),
                              n_elements=n)
        assert sol.converged and sol.stable, sol.message
        ports = sol.ports
        assert ports["sliding"].tolist() == [False]
        force, friction = ports["force"][0], ports["friction"][0]
        assert np.linalg.norm(friction) <= 2.0 * needed * np.linalg.norm(force - friction)
        assert abs(ports["arc_length"][0] - s_port) < 0.2 / n**2
        if n == 20:
            assert abs(ports["arc_length"][0] - rest_arc) < 1e-12
        tip = sol.tip_position
        tips.append(np.hypot(tip[0] - ref["tip"][0], tip[2] - ref["tip"][1]))
        forces.append(np.linalg.norm(force[[0, 2]] - ref["force"]))
    for errors in (tips, forces):
        assert all(a / b > 3.5 for a, b in zip(errors, errors[1:], strict=False)), errors
    assert tips[-1] < 5e-6 and forces[-1] < 2e-4 * np.linalg.norm(ref["force"])
    # A third of the friction it needs: the rod slides, at the cone's edge.
    sol = softspine.solve(curled_through_port(curvature, s_port, load, needed / 3.0),
                          n_elements=40)
    assert sol.converged and sol.ports["sliding"].tolist() == [True]
    force, friction = sol.ports["force"][0], sol.ports["friction"][0]
    np.testing.assert_allclose(np.linalg.norm(friction),
                               needed / 3.0 * np.linalg.norm(force - friction), rtol=1e-9)
    assert abs(sol.tip_position[2] - ref["tip"][1]) > 1e-3


def test_no_port_friction_is_the_frictionless_port_and_friction_comes_back():
    scene = port_scene((0.5, 0.1), 1.0, 2.0)[0]
    plain = softspine.solve(scene, n_elements=20)
    scene["ports"][0]["friction"] = 0.0
    zero = softspine.solve(scene, n_elements=20)
    np.testing.assert_array_equal(zero.positions, plain.positions)
    assert "friction" not in softspine.Scene(scene).to_dict()["ports"][0]
    assert plain.ports["sliding"].tolist() == [False]
    np.testing.assert_array_equal(plain.ports["friction"], 0.0)
    scene["ports"][0]["friction"] = 0.4
    assert softspine.Scene(scene).to_dict()["ports"][0]["friction"] == 0.4
    sol = softspine.solve(scene, n_elements=20)
    for back in (softspine.Solution.from_dict(sol.to_dict()),
                 softspine.Solution.from_json(sol.to_json())):
        for key, value in sol.ports.items():
            np.testing.assert_array_equal(back.ports[key], value)


@pytest.mark.parametrize("mu, sliding", [(0.3, True), (3.0, False)])
def test_sensitivities_through_a_frictional_port_are_those_of_the_step(mu, sliding):
    # The tip force moved from a loaded start, one step: the rod slides
    # through the port (or sticks in it), and the sensitivities keep that
    # state. Against central differences of the same step. A sliding port's
    # friction turns with the chord, which the Jacobian's curvature block
    # had made symmetric: the derivatives were 5e-6 off (and the step took
    # 5 Newton iterations, 3 now).
    scene = port_scene((0.5, 0.1), 1.0)[0]
    scene["ports"][0]["friction"] = mu
    start = softspine.solve(scene, n_elements=20)
    force = np.array(scene["tip_force"]) + [0.0, 0.1, -0.2]
    step = softspine.solve({**scene, "tip_force": list(force)}, n_elements=20, initial=start)
    assert step.ports["sliding"].tolist() == [sliding], step.message
    check_step_sensitivity(scene, start, force, 20, lambda sol: sol.ports["sliding"].tolist())


@pytest.mark.parametrize("mu", [0.3, 1.0])
def test_a_robot_through_a_frictional_port_reaches_its_targets_at_the_end_of_its_history(mu):
    # The robot hangs through a port with friction and inserts itself:
    # each answer is one step of its history (from rest, then from the
    # last answer), the rod sliding through the port with mu times the
    # force across. A forward solve of that history, apart from the
    # search, lands on the target.
    robot = inserted_robot(ports=[{"position": [0, 0, -0.3], "friction": mu}])
    targets = [[0.0, 0.05, -1.0], [0.01, 0.06, -1.02], [0.02, 0.07, -1.04]]
    previous = None
    for r, target in zip(robot.track(targets), targets, strict=True):
        assert r.reached, r.message
        ports = r.solution.ports
        assert ports["sliding"].tolist() == [True]
        across = np.linalg.norm(ports["force"][0] - ports["friction"][0])
        assert np.linalg.norm(ports["friction"][0]) == pytest.approx(mu * across, rel=1e-8)
        scene = robot.scene(r.rest_curvature, insertion=r.insertion)
        sol = softspine.solve(scene, n_elements=20, residual_tol=1e-12, initial=previous)
        assert np.linalg.norm(sol.tip_position - target) < 1e-9
        previous = r.solution


def test_a_rod_fed_through_a_frictional_port_by_its_base_meets_shooting_sliding_forward():
    # The base moves 0.1 m along the rod in five steps, each warm from the
    # last Solution: its history starts from that rod where it stood
    # (Solver::solve_after), so the rod slides forward through the port and
    # the port's friction pushes it back towards the base; against
    # `through_port` with the friction that way, at the final geometry.
    # (Cold, the rod is inserted before the loads ramp and slides back.)
    mu, port = 0.3, (0.6, 0.1)
    ref = through_port(1.0, 1.0, (port[0] - 0.1, port[1]), 0.5, 1.0, friction=mu, slide=-1.0)
    tips, arcs = [], []
    for n in (20, 40, 80):
        previous = None
        for d in np.linspace(0.0, 0.1, 6):
            scene = port_scene(port, 0.5, 1.0)[0]
            scene["base_position"] = [d, 0.0, 0.0]
            scene["ports"][0]["friction"] = mu
            sol = softspine.solve(scene, n_elements=n, initial=previous)
            assert sol.converged and sol.stable, (d, sol.message)
            previous = sol
        assert sol.ports["sliding"].tolist() == [True]
        friction = sol.ports["friction"][0]
        assert friction[0] < 0.0
        cold = softspine.solve(scene, n_elements=n)
        assert cold.ports["friction"][0][0] > 0.0
        tip = sol.tip_position - [0.1, 0.0, 0.0]
        tips.append(np.hypot(tip[0] - ref["tip"][0], tip[2] - ref["tip"][1]))
        arcs.append(abs(sol.ports["arc_length"][0] - ref["arc_length"]))
    assert all(a / b > 3.0 for a, b in zip(arcs, arcs[1:], strict=False)), arcs
    assert tips[-1] < 1e-4 and tips[0] / tips[-1] > 10, tips


def test_a_robot_inserted_step_by_step_through_a_frictional_port_feels_it_against_the_insertion():
    # The robot hangs down through a port 2 cm off its axis: inserted in
    # steps, each from the last Solution, the port's friction pushes it up,
    # against the insertion, at mu times its force across.
    robot = inserted_robot(ports=[{"position": [0, 0.02, -0.3], "friction": 0.3}])
    previous = robot.forward(insertion=0.0)
    for d in (0.05, 0.1, 0.15, 0.2):
        sol = robot.forward(insertion=d, initial=previous)
        assert sol.converged and sol.ports["sliding"].tolist() == [True], sol.message
        force, friction = sol.ports["force"][0], sol.ports["friction"][0]
        assert friction[2] > 0.0
        np.testing.assert_allclose(np.linalg.norm(friction),
                                   0.3 * np.linalg.norm(force - friction), rtol=1e-9)
        previous = sol


@pytest.mark.parametrize("mu", [0.0, 0.3])
def test_a_frictional_port_with_a_held_tip_is_solved(mu):
    # A held tip's load path solves the released rod first in the whole
    # scene's workspace: the friction row's place was counted from the held
    # points' residuals there, past the end of the step's matrix (a panic,
    # "Matrix index out of bounds", before the fix).
    scene = port_scene((0.5, 0.1), 1.0)[0]
    scene["ports"][0]["friction"] = mu
    scene["tip"] = {"type": "pinned", "position": [0.95, 0.0, 0.2]}
    arcs = []
    for n in (20, 40, 80):
        sol = softspine.solve(scene, n_elements=n)
        assert sol.converged and sol.stable, sol.message
        np.testing.assert_allclose(sol.tip_position, [0.95, 0.0, 0.2], atol=1e-12)
        force, friction = sol.ports["force"][0], sol.ports["friction"][0]
        assert sol.ports["sliding"].tolist() == [mu > 0.0]
        np.testing.assert_allclose(np.linalg.norm(friction),
                                   mu * np.linalg.norm(force - friction), rtol=1e-9, atol=1e-15)
        arcs.append(sol.ports["arc_length"][0])
    assert abs(arcs[2] - arcs[1]) < abs(arcs[1] - arcs[0]) / 3.0, arcs
