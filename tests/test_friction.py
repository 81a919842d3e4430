"""Coulomb friction at obstacle contacts (issue 28, deliverable 5).

A precurved rod clamped along +x bends down onto a floor; its weight pushes
the tip outward. Where the friction needed to hold the tip is within the cone
the tip sticks: the answer is the same rod with its tip pinned where it
touched (the held-point solve, another code path). Where it is not, the tip
slides: its friction is mu times its normal force, against its move, and the
rod is in equilibrium under that force (the same rod with no obstacle and the
contact's force at its tip, the free solve). Friction makes the answer the end
of a history: unloading from a loaded state ends elsewhere than loading to the
same weight from the rest shape."""

from __future__ import annotations

import math

import numpy as np
import pytest
from friction_reference import check_step_sensitivity

import softspine

ALONG_X = [math.sqrt(0.5), 0.0, math.sqrt(0.5), 0.0]
N = 40


def arc(weight: float, mu: float | None = None, floor: float = 0.0, **extra) -> dict:
    """A rod bent in the x-z plane (curvature 2/m), along +x at its clamp, under
    its weight; with ``mu``, a floor at height ``floor`` with that friction."""
    scene = {
        "length": 1.0,
        "stiffness": {"kx": 1.0, "ky": 1.0, "kz": 1.0},
        "base_quaternion": ALONG_X,
        "rest_curvature": [[0.0, 2.0]],
        "gravity": {"linear_density": weight, "vector": [0.0, 0.0, -1.0]},
    }
    if mu is not None:
        scene["obstacles"] = [{"shape": "half_space", "point": [0.0, 0.0, floor],
                               "normal": [0.0, 0.0, 1.0], "friction": mu}]
    scene.update(extra)
    return scene


@pytest.fixture(scope="module")
def rest_tip() -> np.ndarray:
    """Where the unloaded rod's tip is: the floor is put there."""
    return softspine.solve(arc(0.0), n_elements=N).tip_position


def test_a_tip_within_its_cone_sticks_where_it_touched(rest_tip):
    pinned = softspine.solve(arc(1.0, tip={"type": "pinned", "position": list(rest_tip)}),
                             n_elements=N)
    assert pinned.converged
    needed = abs(pinned.tip_reaction_force[0]) / pinned.tip_reaction_force[2]
    assert 0.03 < needed < 0.05  # measured 0.0419
    for mu in (0.05, 0.3, 5.0):
        sol = softspine.solve(arc(1.0, mu, floor=rest_tip[2]), n_elements=N)
        assert sol.converged and sol.stable, sol.message
        c = sol.contacts
        assert len(c["force"]) == 1 and not c["sliding"][0]
        np.testing.assert_allclose(sol.positions, pinned.positions, atol=1e-9)
        # The floor's force is the pin's reaction: normal and friction.
        assert c["force"][0] == pytest.approx(pinned.tip_reaction_force[2], rel=1e-8)
        np.testing.assert_allclose(c["friction"][0], [pinned.tip_reaction_force[0], 0, 0],
                                   atol=1e-9)
        assert np.linalg.norm(c["friction"][0]) <= mu * c["force"][0]


@pytest.mark.parametrize("mu", [0.01, 0.02, 0.04])
def test_a_tip_outside_its_cone_slides_with_mu_times_its_normal_force(rest_tip, mu):
    sol = softspine.solve(arc(1.0, mu, floor=rest_tip[2]), n_elements=N)
    assert sol.converged and sol.stable, sol.message
    c = sol.contacts
    assert len(c["force"]) == 1 and c["sliding"][0]
    friction, normal = c["friction"][0], c["force"][0]
    assert np.linalg.norm(friction) == pytest.approx(mu * normal, rel=1e-12)
    # Against the tip's move along the floor (it slid inward, -x).
    moved = sol.tip_position - rest_tip
    assert moved[0] < -1e-5
    assert np.dot(friction, moved) < 0.0
    assert abs(friction[1]) < 1e-14 and abs(friction[2]) < 1e-14
    # The rod is in equilibrium under that force: the free solve with it at
    # the tip (no obstacle, no contact code) gives the same shape, the tip on
    # the floor.
    force = normal * c["normal"][0] + friction
    free = softspine.solve(arc(1.0, tip_force=list(force)), n_elements=N)
    np.testing.assert_allclose(free.positions, sol.positions, atol=1e-8)
    assert abs(free.tip_position[2] - rest_tip[2]) < 1e-8


def test_more_friction_slides_less(rest_tip):
    slid = [softspine.solve(arc(1.0, mu, floor=rest_tip[2]), n_elements=N).tip_position[0]
            - rest_tip[0] for mu in (0.0, 0.01, 0.02, 0.03, 0.04, 0.05)]
    assert all(a < b for a, b in zip(slid, slid[1:], strict=False)), slid
    assert slid[-1] == pytest.approx(0.0, abs=1e-12)


def test_the_answer_is_the_end_of_its_history(rest_tip):
    # Loaded to w = 1 from the rest shape, then unloaded to 0.5 from there (a
    # warm start's history starts at its shape), against 0.5 from the rest
    # shape: the tip slid inward under w = 1 and stays there as the weight
    # halves (its friction back inside the cone), where loading straight to
    # 0.5 slides it half as far.
    mu, floor = 0.02, rest_tip[2]
    loaded = softspine.solve(arc(1.0, mu, floor=floor), n_elements=N)
    direct = softspine.solve(arc(0.5, mu, floor=floor), n_elements=N)
    unloaded = softspine.solve(arc(0.5, mu, floor=floor), n_elements=N, initial=loaded)
    for sol in (loaded, direct, unloaded):
        assert sol.converged and sol.stable, sol.message
    x = [s.tip_position[0] - rest_tip[0] for s in (loaded, direct, unloaded)]
    assert x[2] == pytest.approx(x[0], abs=1e-10) and x[1] - x[0] > 5e-4, x
    assert loaded.contacts["sliding"][0] and direct.contacts["sliding"][0]
    c = unloaded.contacts
    assert not c["sliding"][0]
    assert np.linalg.norm(c["friction"][0]) < mu * c["force"][0]
    # Stuck, it is the rod pinned where the loading left its tip.
    pinned = softspine.solve(arc(0.5, tip={"type": "pinned", "position": list(
        loaded.tip_position)}), n_elements=N)
    np.testing.assert_allclose(unloaded.positions, pinned.positions, atol=1e-9)


def test_a_leaning_rod_slides_whatever_its_friction():
    # A straight rod leaning on the floor from a clamp: its tip is a rod's
    # length from the clamp, which a bent rod cannot keep, so it must slide
    # (no finite friction holds it); the shape is the free solve's under the
    # contact's force.
    alpha = math.radians(30.0)
    half = (math.pi / 2 + alpha) / 2
    lean = {"length": 1.0, "stiffness": {"kx": 1.0, "ky": 1.0, "kz": 1.0},
            "base_quaternion": [math.cos(half), 0.0, math.sin(half), 0.0],
            "base_position": [0.0, 0.0, math.sin(alpha)],
            "gravity": {"linear_density": 1.0, "vector": [0.0, 0.0, -1.0]}}
    for mu in (0.1, 2.0):
        floor = {"shape": "half_space", "point": [0, 0, 0], "normal": [0, 0, 1],
                 "friction": mu}
        sol = softspine.solve({**lean, "obstacles": [floor]}, n_elements=N)
        assert sol.converged, sol.message
        c = sol.contacts
        assert c["sliding"][0]
        assert np.linalg.norm(c["friction"][0]) == pytest.approx(mu * c["force"][0],
                                                                 rel=1e-12)
        force = c["force"][0] * c["normal"][0] + c["friction"][0]
        free = softspine.solve({**lean, "tip_force": list(force)}, n_elements=N)
        np.testing.assert_allclose(free.positions, sol.positions, atol=1e-8)


def test_zero_friction_is_the_frictionless_answer(rest_tip):
    plain = arc(1.0, 0.0, floor=rest_tip[2])
    del plain["obstacles"][0]["friction"]
    a = softspine.solve(plain, n_elements=N)
    b = softspine.solve(arc(1.0, 0.0, floor=rest_tip[2]), n_elements=N)
    np.testing.assert_array_equal(a.positions, b.positions)
    np.testing.assert_array_equal(b.contacts["friction"], np.zeros((1, 3)))


def test_friction_is_written_back_and_survives_a_round_trip(rest_tip):
    scene = softspine.Scene(arc(1.0, 0.3, floor=rest_tip[2]))
    assert scene.to_dict()["obstacles"][0]["friction"] == 0.3
    sol = softspine.solve(scene, n_elements=N)
    d = sol.to_dict()
    assert d["contact_sliding"].dtype == bool
    again = softspine.Solution.from_dict(d)
    np.testing.assert_array_equal(again.contacts["friction"], sol.contacts["friction"])
    np.testing.assert_array_equal(again.contacts["sliding"], sol.contacts["sliding"])


@pytest.mark.parametrize("mu", [-0.1, float("nan"), float("inf")])
def test_a_bad_friction_is_refused_by_name(mu):
    with pytest.raises(ValueError, match=r"obstacles\[0\]\.friction"):
        softspine.Scene(arc(1.0, mu))


@pytest.mark.parametrize("mu, sliding", [(0.3, False), (0.02, True)])
def test_sensitivities_with_friction_are_those_of_the_step_from_where_the_rod_stood(
        rest_tip, mu, sliding):
    # With friction an equilibrium ends a step of its history, and its
    # sensitivities keep each contact's state: a sticking tip stays at its
    # anchor (no derivative at all), a sliding one slides on with mu N
    # against its move since the step's start, its direction turning with it
    # (docs/model.md). Against central differences of that step: from the
    # same Solution to the tip force moved either way.
    scene = arc(1.0, mu, floor=rest_tip[2])
    start = softspine.solve(scene, n_elements=N)
    force = np.array([0.05, 0.0, -0.1])
    step = softspine.solve({**scene, "tip_force": list(force)}, n_elements=N, initial=start)
    assert step.contacts["sliding"].tolist() == [sliding], step.message
    sens = check_step_sensitivity(scene, start, force, N,
                                  lambda sol: sol.contacts["sliding"].tolist())
    # The free rod's tip moves by 0.09 m/N along the floor; stuck, not at all.
    along = np.abs(sens[:2, :2]).max()
    assert along < 1e-12 if not sliding else along > 0.05


def test_a_rod_lying_on_a_frictional_floor_sticks_with_no_friction():
    # Every node touches and sticks: the sticking rows hold each node twice
    # over (the chords' lengths are fixed already), which made the step's
    # matrix singular (no convergence), and before that panicked twice (a
    # mixed step left the Schur right-hand side its own size; a restart from
    # the rest shape kept the last attempt's sticking contacts, unanchored).
    # The rows' compliance (friction.rs) picks the least friction that holds
    # them: none, the weight pressing straight down.
    scene = {"length": 1.0, "stiffness": {"kx": 1.0, "ky": 1.0, "kz": 1.0},
             "base_quaternion": ALONG_X, "rest_curvature": [[2.0, 0.0]],
             "gravity": {"linear_density": 1.0, "vector": [0.0, 0.0, -1.0]},
             "obstacles": [{"shape": "half_space", "point": [0, 0, 0], "normal": [0, 0, 1],
                            "friction": 0.3}]}
    sol = softspine.solve(scene, n_elements=N)
    assert sol.converged and sol.stable, sol.message
    c = sol.contacts
    assert len(c["force"]) == N and not c["sliding"].any()
    assert np.abs(c["friction"]).max() < 1e-9
    # The floor carries the weight but the base's half element.
    assert c["force"].sum() == pytest.approx(1.0 - 0.5 / N, rel=1e-9)
    rest = softspine.solve({**scene, "obstacles": [], "gravity": {"linear_density": 0.0,
                                                                  "vector": [0, 0, -1.0]}},
                           n_elements=N)
    np.testing.assert_allclose(sol.positions, rest.positions, atol=1e-12)


def test_a_robot_curled_into_a_frictional_wall_is_held_back_the_more_friction():
    # The seed's robot bent into a wall (tests/test_contact.py): its rest
    # shape passes through the wall, so the history is the curl from
    # straight under its 30 g (docs/model.md, "Coulomb friction"). Curling,
    # it pushes its tip up along the wall; friction holds it back, down, at
    # mu times the normal force (it slid all the way), and more friction
    # leaves the tip lower.
    wall = {"shape": "half_space", "point": [0.15, 0, 0], "normal": [-1, 0, 0]}
    bend = np.zeros((10, 2))
    bend[:, 1] = 0.6
    plain = softspine.Robot({"obstacles": [wall]}).forward(bend, load=0.03)
    heights = []
    for mu in (0.05, 0.5, 2.0):
        robot = softspine.Robot({"obstacles": [{**wall, "friction": mu}]})
        sol = robot.forward(bend, load=0.03)
        assert sol.converged and sol.stable, sol.message
        assert "curled to it from straight" in sol.message
        c = sol.contacts
        assert len(c["force"]) == 1
        assert c["friction"][0][2] < 0.0
        # At the cone's edge: sliding, or come to rest there (within the
        # sticking rows' cone slack, 1e-9, and the solve's tolerance).
        assert np.linalg.norm(c["friction"][0]) == pytest.approx(mu * c["force"][0], rel=1e-8)
        heights.append(sol.tip_position[2] - plain.tip_position[2])
    assert 0.0 > heights[0] > heights[1] > heights[2], heights


def test_a_sensitivity_moving_the_rod_against_what_sticks_is_refused_by_name(rest_tip):
    # The base moved under a stuck tip: the sticking rows' own motion is not
    # differenced, and the answer was the tip dragged along with the base
    # (the floor does not move); refused by name while anything sticks.
    solver = softspine.Solver(arc(1.0, 0.3, floor=rest_tip[2]), n_elements=N)
    assert solver.solve().contacts["sliding"].tolist() == [False]
    with pytest.raises(ValueError, match=r"base_position\[0\].*sticks"):
        solver.sensitivity("base_position[0]")
    assert solver.sensitivity("tip_force[0]").tip_position.shape == (3, 1)


BALL = {"shape": "sphere", "centre": [0.08, 0.0, -0.5], "radius": 0.08}


def settled_tip(robot: softspine.Robot, curvature, previous=None) -> np.ndarray:
    """The tip at the end of an inverse answer's history (its muscles' rest
    `curvature`), solved forward apart from the search: from rest along the
    load path, or one step from `previous` (a Solution), at the inverse
    solver's tolerance."""
    scene = robot.scene(curvature, load=0.03)
    sol = softspine.solve(scene, n_elements=robot.n_elements, residual_tol=1e-12,
                          initial=previous)
    assert sol.converged, sol.message
    return sol.tip_position


@pytest.mark.parametrize("mu", [0.1, 1.0])
def test_the_inverse_kinematics_with_friction_ends_its_history_on_the_target(mu):
    # The seed's robot reaches past a ball it leans on. With friction an
    # answer is the end of its history: from rest, the load path to the
    # answer's actuation (docs/model.md). The contact slides over the ball
    # with mu N, and the frictionless robot at that actuation misses (by
    # 4e-5 m with mu = 0.1: the search is not the frictionless one's).
    target = np.array([0.1, 0.0, -0.93])
    robot = softspine.Robot({"obstacles": [{**BALL, "friction": mu}]})
    r = robot.inverse(target, load=0.03)
    assert r.reached, r.message
    c = r.solution.contacts
    assert c["sliding"].tolist() == [True]
    assert np.linalg.norm(c["friction"][0]) == pytest.approx(mu * c["force"][0], rel=1e-8)
    assert np.linalg.norm(settled_tip(robot, r.rest_curvature) - target) < 1e-9
    plain = softspine.Robot({"obstacles": [BALL]})
    assert np.linalg.norm(plain.forward(r.rest_curvature, load=0.03).tip_position
                          - target) > 1e-5


def test_the_inverse_kinematics_reaches_along_a_wall_its_tip_sticks_to():
    # The answer's tip sticks on the wall, where its exact derivative is
    # nil along the wall: the descent's Jacobian lets what sticks go (with
    # that derivative the search needed a second start, 80 iterations
    # against 16, and left the wall for an S-bend).
    wall = {"shape": "half_space", "point": [0.15, 0, 0], "normal": [-1, 0, 0],
            "friction": 0.5}
    robot = softspine.Robot({"obstacles": [wall]})
    target = np.array([0.13, 0.03, -0.94])
    r = robot.inverse(target, load=0.03)
    assert r.reached and r.starts == 1, r.message
    c = r.solution.contacts
    assert c["sliding"].tolist() == [False] and c["force"][0] > 1e-3
    assert 0.0 < np.linalg.norm(c["friction"][0]) < 0.5 * c["force"][0]
    assert np.linalg.norm(settled_tip(robot, r.rest_curvature) - target) < 1e-9


def test_tracking_with_friction_steps_from_each_answer_and_a_batch_from_rest():
    # Along a path each answer is one step of the robot's history from the
    # last (a forward solve from that Solution lands on the target); a
    # batch's targets are each on their own, from rest, whatever order.
    robot = softspine.Robot({"obstacles": [{**BALL, "friction": 0.3}]})
    targets = np.array([[0.1, 0.0, -0.93], [0.1, 0.01, -0.935], [0.1, 0.02, -0.94]])
    path = robot.track(targets, load=0.03)
    previous = None
    for r, target in zip(path, targets, strict=True):
        assert r.reached, r.message
        assert np.linalg.norm(settled_tip(robot, r.rest_curvature, previous) - target) < 1e-9
        previous = r.solution
    assert np.linalg.norm(settled_tip(robot, path[2].rest_curvature) - targets[2]) > 1e-6
    batch = robot.inverse_batch(targets[::-1], load=0.03)
    for k, target in enumerate(targets[::-1]):
        assert batch.reached[k]
        assert np.linalg.norm(settled_tip(robot, batch.rest_curvature[k]) - target) < 1e-9


@pytest.mark.parametrize("obstacle, mu, curvature", [
    ({"shape": "half_space", "point": [0.15, 0, 0], "normal": [-1, 0, 0]}, 0.1, 3.0),
    ({"shape": "half_space", "point": [0.15, 0, 0], "normal": [-1, 0, 0]}, 0.1, 4.0),
    ({"shape": "half_space", "point": [0.15, 0, 0], "normal": [-1, 0, 0]}, 0.5, 2.0),
    ({"shape": "sphere", "centre": [0.25, 0, -0.6], "radius": 0.12}, 0.1, 1.0),
])
def test_a_robot_whose_rest_shape_passes_through_a_frictional_obstacle_is_curled_to_it(
        obstacle, mu, curvature):
    # The load path from a rest shape through the obstacle has no start: each
    # of these ended not converged or at the iteration limit before the curl.
    robot = softspine.Robot({"obstacles": [{**obstacle, "friction": mu}]})
    sol = robot.forward(np.full((10, 2), [0.0, curvature]), load=0.03)
    assert sol.converged and sol.stable, sol.message
    assert "curled to it from straight" in sol.message
    c = sol.contacts
    assert len(c["force"]) >= 1 and (c["force"] >= 0.0).all()
    friction = np.linalg.norm(c["friction"], axis=1)
    assert (friction <= mu * c["force"] * (1 + 1e-9) + 1e-12).all()
    if obstacle["shape"] == "half_space":
        assert sol.positions[:, 0].max() <= 0.15 + 1e-9


@pytest.mark.parametrize("curvature", [0.6, 2.0])
def test_the_curl_with_vanishing_friction_ends_at_the_frictionless_equilibrium(curvature):
    # The curl is a history; without friction the answer has none: with mu
    # = 1e-9 it lands where the frictionless direct solve does.
    wall = {"shape": "half_space", "point": [0.15, 0, 0], "normal": [-1, 0, 0]}
    bend = np.full((10, 2), [0.0, curvature])
    plain = softspine.Robot({"obstacles": [wall]}).forward(bend, load=0.03)
    tiny = softspine.Robot({"obstacles": [{**wall, "friction": 1e-9}]}).forward(bend, load=0.03)
    assert plain.converged and tiny.converged
    assert "curled" not in plain.message and "curled to it from straight" in tiny.message
    np.testing.assert_allclose(tiny.positions, plain.positions, atol=1e-10)


def pushed_rod(push: float) -> dict:
    """A straight rod lying on a frictional floor along +x, pushed sideways
    (+y) at its free end."""
    return {"length": 1.0, "stiffness": {"kx": 1.0, "ky": 1.0, "kz": 1.0},
            "base_quaternion": ALONG_X, "tip_force": [0.0, push, 0.0],
            "gravity": {"linear_density": 1.0, "vector": [0.0, 0.0, -1.0]},
            "obstacles": [{"shape": "half_space", "point": [0, 0, 0], "normal": [0, 0, 1],
                           "friction": 0.3}]}


@pytest.mark.parametrize("push", [0.05, 0.1])
def test_a_rod_pushed_along_a_floor_slides_partly_backwards_as_the_reference(push):
    # Pushed at its tip by 0.05 or 0.1 of its weight (the friction could
    # hold six or three times that): the sticking stretch's end carries a
    # moment, which a sticking stretch of a discrete rod passes on as
    # alternating shears above every cone. The rows' own compliance cycled
    # there (no convergence at n = 20); the relaxed levels (constrained.rs)
    # find the answer, which has contacts sliding backwards next to the
    # forward slip zone, as the reference's (friction_reference.py, an
    # Euler-Bernoulli beam of Hermite elements, the convex minimisation
    # solved exactly). Sticking contacts may creep by 3e-9 L on the relaxed
    # rows (friction.rs), which moves the tip by under 0.1 % of its move.
    from friction_reference import pushed_along_a_floor

    reference = pushed_along_a_floor(1.0, 1.0, 0.3, 1.0, push, 320)[-1]
    errors = []
    for n in (20, 40, 80):
        sol = softspine.solve(pushed_rod(push), n_elements=n)
        assert sol.converged, sol.message
        c = sol.contacts
        sliding = c["sliding"].astype(bool)
        friction_y = np.asarray(c["friction"])[:, 1]
        assert (sliding & (friction_y < 0)).any() and (sliding & (friction_y > 0)).any()
        # Sliding: mu times the normal force; sticking: within the cone.
        mu_lambda = 0.3 * np.asarray(c["force"])
        size = np.linalg.norm(c["friction"], axis=1)
        np.testing.assert_allclose(size[sliding], mu_lambda[sliding], rtol=1e-9)
        assert (size[~sliding] <= mu_lambda[~sliding] * (1 + 1e-9)).all()
        errors.append(abs(sol.tip_position[1] - reference) / reference)
    # Second order in n: 1.2 %, 0.57 %, 0.14 % of the tip's move (0.05) and
    # 0.59 %, 0.15 %, 0.044 % (0.1; the reference's own error at 320
    # elements is some 0.01 %).
    assert errors[2] < 2e-3
    assert errors[0] / errors[1] > 1.8 and errors[1] / errors[2] > 3.0, errors


@pytest.mark.parametrize(("mu", "load"),
                         [(0.3, 2.0), (1.0, 1.0), (0.05, 0.5), (0.3, 0.1), (0.3, 0.01)])
def test_a_rod_sliding_over_a_frictional_edge_at_a_node_meets_shooting(mu, load):
    # A cantilever pushed onto a knife edge that stands under a node (0.6 of
    # its length, a node at every n here), with friction: as it bends it
    # slides back over the edge, which pushes it towards its tip by mu times
    # the normal force. Against shooting (a one-sided port with that
    # friction, `through_port`). Before the sliding direction followed the
    # slip within a solve, the direction turned at each solve's end chased
    # the sideways slip its own turn made, and these ran to the iteration
    # limit (7 of 30 such scenes).
    from contact_reference import through_port
    from test_contact import knife_edge_scene
    ref = through_port(1.0, 1.0, (0.6, 0.0), load, friction=mu, slide=1.0)
    tips, forces = [], []
    for n in (20, 40, 80):
        scene = knife_edge_scene(load)
        scene["obstacles"][0]["friction"] = mu
        sol = softspine.solve(scene, n_elements=n)
        assert sol.converged and sol.stable, sol.message
        c = sol.contacts
        assert len(c["force"]) == 1 and c["sliding"][0]
        force = c["force"][0] * c["normal"][0] + c["friction"][0]
        # Coulomb's law at the edge, towards the tip, in the rod's plane.
        np.testing.assert_allclose(np.linalg.norm(c["friction"][0]), mu * c["force"][0],
                                   rtol=1e-9)
        assert c["friction"][0][0] > 0.0 and abs(force[1]) < 1e-9 * abs(force[2])
        forces.append(np.linalg.norm(force[[0, 2]] - ref["force"]) / np.linalg.norm(ref["force"]))
        tips.append(np.hypot(sol.tip_position[0] - ref["tip"][0],
                             sol.tip_position[2] - ref["tip"][1]))
        assert abs(c["arc_length"][0] - ref["arc_length"]) < 0.1 / n**2
    # The tip at second order, the force (a kink beside the node) at first
    # (measured 3.1 to 4.0 and 1.9 to 2.4 a halving).
    assert all(a / b > 2.8 for a, b in zip(tips, tips[1:], strict=False)), tips
    assert all(a / b > 1.8 for a, b in zip(forces, forces[1:], strict=False)), forces
    assert tips[-1] < 5e-5 and forces[-1] < 5e-3, (tips, forces)


def floor_push(mu: float | None, span: float) -> dict:
    """A heavy isotropic rod lying along +x on a floor, its tip pinned on
    the floor at `span` of its length from the base; `mu` the floor's
    friction (None: frictionless)."""
    floor = {"shape": "half_space", "point": [0.0, 0.0, 0.0], "normal": [0.0, 0.0, 1.0]}
    if mu is not None:
        floor["friction"] = mu
    return {"length": 1.0, "stiffness": {"kx": 1.0, "ky": 1.0, "kz": 1.0},
            "base_quaternion": ALONG_X, "obstacles": [floor],
            "gravity": {"linear_density": 1.0, "vector": [0.0, 0.0, -9.81]},
            "tip": {"type": "pinned", "position": [span, 0.0, 0.0]}}


@pytest.mark.parametrize("mu", [0.1, 1.0])
def test_a_heavy_rod_pushed_along_a_frictional_floor_snakes_sliding_at_its_cone(mu):
    # Pushed along its line, the rod buckles sideways along the floor and
    # every contact slides (at mu times its normal force). Not converged
    # before (0 of 12 such scenes, mu 0.01 to 1, 0.9 to 0.99 of the length;
    # 11 now): the stability verdict held every contact sticking, whose rows
    # repeat where a whole stretch sticks (each chord's length held twice),
    # and read the repeats as a neutral direction; every step was then
    # "unstable" and retried shorter until the budget ran out. Also the
    # first step from the buckling bump was retried for moving far from it,
    # and every step climbed the relaxed levels from the top.
    tips = []
    for n in (20, 40, 80):
        sol = softspine.solve(floor_push(mu, 0.95), n_elements=n)
        assert sol.converged and sol.stable, sol.message
        c = sol.contacts
        assert c["sliding"].all() and len(c["force"]) == n - 1
        np.testing.assert_allclose(np.linalg.norm(c["friction"], axis=1), mu * c["force"],
                                   rtol=1e-9, atol=1e-12)
        assert np.abs(sol.positions[:, 2]).max() < 1e-9
        assert np.abs(sol.positions[:, 1]).max() > 0.1
        tips.append(sol.tip_reaction_force[0])
    # The pin's push converges as n doubles (first order here: measured
    # differences 0.052, 0.022 N for mu = 0.3).
    assert abs(tips[2] - tips[1]) < 0.6 * abs(tips[1] - tips[0]), tips


def test_a_rod_pushed_along_a_floor_of_vanishing_friction_is_the_frictionless_one():
    # The friction machinery (sticking rows, sliding directions, relaxed
    # levels, the stability verdict with stuck stretches) ends where the
    # frictionless contact does as mu goes to zero.
    for n in (20, 40):
        free = softspine.solve(floor_push(None, 0.95), n_elements=n)
        slight = softspine.solve(floor_push(1e-6, 0.95), n_elements=n)
        assert free.converged and slight.converged and slight.stable, slight.message
        # Mirror equilibria: compare on the side each took.
        side = np.sign(free.positions[n // 2, 1]) * np.sign(slight.positions[n // 2, 1])
        np.testing.assert_allclose(slight.positions * [1.0, side, 1.0], free.positions,
                                   atol=1e-6)


@pytest.mark.parametrize("mu", [0.1, 0.3])
def test_a_rod_sagging_onto_a_frictional_floor_is_pushed_along_it_within_the_default_budget(mu):
    # The base 1 mm above the floor: the loaded rod sags onto it along a
    # planar stretch. Not converged before at n = 40 and 80 (iteration
    # limit): the held leg tried the plane first, where the rod can only
    # arch up off the floor (a failure from the flat rod's first step that
    # cost half the budget); from the bump out of the plane the top relaxed
    # level had 8 iterations to leave it; and every frictional step took
    # the levels' 10 or more iterations, so the steps never grew past 1e-3.
    pushes = []
    for n in (20, 40, 80):
        lying = softspine.solve(floor_push(mu, 0.95), n_elements=n)
        scene = floor_push(mu, 0.95)
        scene["obstacles"][0]["point"] = [0.0, 0.0, -0.001]
        above = softspine.solve(scene, n_elements=n)
        assert above.converged and above.stable, above.message
        c = above.contacts
        assert c["sliding"].all() and len(c["force"]) >= n // 3
        np.testing.assert_allclose(np.linalg.norm(c["friction"], axis=1), mu * c["force"],
                                   rtol=1e-9, atol=1e-12)
        assert above.positions[:, 2].min() > -0.001 - 1e-9
        assert np.abs(above.positions[:, 1]).max() > 0.1
        # Its ends lift off (the base's millimetre, the pin's), the rest
        # slides as the rod lying on the floor does: the same push to 1 %
        # (measured 0.3 to 0.9 %).
        push = above.tip_reaction_force[0]
        assert abs(push / lying.tip_reaction_force[0] - 1.0) < 0.01
        pushes.append(push)
    assert abs(pushes[2] - pushes[1]) < 0.6 * abs(pushes[1] - pushes[0]), pushes


def test_a_solver_solving_cold_again_repeats_its_frictional_solve():
    # Friction's relaxed levels (whether a step needed them, and where the
    # last relaxed solve ended) belong to one solve: they were kept on the
    # Solver, so a second cold solve of the same scene skipped the direct
    # attempt at the rows' own compliance and took another path (56 then 89
    # iterations on this knife edge; 70 then 65 on the floor).
    from test_contact import knife_edge_scene
    knife = knife_edge_scene(2.0)
    knife["obstacles"][0]["friction"] = 0.3
    for scene in (knife, floor_push(0.3, 0.95)):
        solver = softspine.Solver(scene, n_elements=20)
        first, again = solver.solve(warm=False), solver.solve(warm=False)
        assert first.converged and again.converged
        assert again.iterations == first.iterations
        np.testing.assert_array_equal(again.positions, first.positions)


def test_a_heavy_rod_sagging_onto_a_floor_of_friction_one_is_pushed_along_it_at_n_80():
    # Bent out of its plane first, the held leg keeps three quarters of the
    # budget (it had half, and needed 414 of its iterations here: the
    # iteration limit before); the in-plane leg after it is the one
    # expected to fail.
    scene = floor_push(1.0, 0.9)
    scene["obstacles"][0]["point"] = [0.0, 0.0, -0.001]
    sol = softspine.solve(scene, n_elements=80)
    assert sol.converged and sol.stable, sol.message
    c = sol.contacts
    sliding = c["sliding"].astype(bool)
    size = np.linalg.norm(c["friction"], axis=1)
    np.testing.assert_allclose(size[sliding], c["force"][sliding], rtol=1e-9, atol=1e-12)
    assert (size[~sliding] <= c["force"][~sliding] * (1 + 1e-9)).all()
    assert np.abs(sol.positions[:, 1]).max() > 0.1
