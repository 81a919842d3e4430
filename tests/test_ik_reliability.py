"""Load-aware IK reaches what the forward model reaches within the muscles'
range, never answers with an unstable equilibrium, and says truly why it
misses; robots whose input cannot be solved are refused naming the key.

The reached fractions are printed (``pytest -s``)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import softspine
from softspine import Robot

from isolated import run_isolated

TILTED = {"base_quaternion": [0.92388, 0.38268, 0, 0], "sections": 5, "n_elements": 20}
# Upright: the base tangent +z, against gravity (the default robot hangs).
UPRIGHT = {"sections": 3, "n_elements": 21, "base_quaternion": [1, 0, 0, 0]}


def in_range_actuations(robot, count, seed):
    """Actuations with every muscle length uniform in the muscles' range."""
    rng = np.random.default_rng(seed)
    lo, hi = robot.muscle_length_range
    shape = (robot.sections, 3)
    return [robot.rest_curvature(rng.uniform(lo, hi, size=shape)) for _ in range(count)]


def reach(robot, load, count, seed=0):
    """Forward-solve in-range actuations, ask the IK for each stable tip; the
    misses (result, true actuation) and the number of tips asked."""
    misses, total = [], 0
    for kappa in in_range_actuations(robot, count, seed):
        fw = robot.forward(kappa, load=load)
        if not (fw.converged and fw.stable):
            continue
        total += 1
        r = robot.inverse(fw.tip_position, load=load)
        # An unstable equilibrium is never an answer.
        assert r.solution.stable or not r.reached, r.message
        if r.reached:
            assert r.tip_miss <= 1e-9
            assert robot.within_bounds(r.rest_curvature)
        else:
            misses.append((r, kappa))
    return misses, total


@pytest.mark.parametrize(
    "data,load",
    [(TILTED, 0.03), (UPRIGHT, 0.08)],
    ids=["tilted-5-sections-30g", "upright-3-sections-80g"],
)
def test_reaches_every_tip_the_forward_model_reaches(data, load):
    robot = Robot(data)
    misses, total = reach(robot, load, 135)
    print(f"\n{data} with {load * 1e3:.0f} g: reached {total - len(misses)}/{total}")
    assert not misses, [r.message for r, _ in misses]


def test_past_buckling_the_straight_reference_is_no_answer():
    """With 200 g the upright straight robot is an unstable equilibrium: the
    IK must start elsewhere, and answer only with stable equilibria."""
    robot = Robot(UPRIGHT)
    assert not robot.forward(np.zeros((3, 2)), load=0.2).stable
    misses, total = reach(robot, 0.2, 30, seed=1)
    print(f"\nupright with 200 g: reached {total - len(misses)}/{total}")
    assert total >= 25 and not misses, [r.message for r, _ in misses]


def test_the_true_actuation_as_reference_is_reached_in_one_iteration():
    robot = Robot(TILTED)
    for kappa in in_range_actuations(robot, 5, 2):
        tip = robot.forward(kappa, load=0.03).tip_position
        r = robot.inverse(tip, load=0.03, reference=kappa)
        assert r.reached and r.iterations == 1, r.message


def test_the_answer_is_the_least_curvature_that_reaches_the_target():
    """Of the curvatures that reach a target, the IK returns the one closest to
    the reference (zero): within range it lies in the row space of the tip's
    Jacobian. Before the engines were one, the first target ended with 20 %
    of its curvature off that span (golden IK target 1)."""
    robot = Robot()
    for target in ([0.049473625570461525, 0.037934201498685226, -0.903208088274919],
                   [0.046288581064953295, 0.2711159538877757, -0.84109366543862]):
        r = robot.inverse(target, load=0.02)
        assert r.reached and robot.within_bounds(r.rest_curvature), r.message
        jac = robot.sensitivity(r.rest_curvature, load=0.02,
                                parameters="rest_curvature").tip_position
        kappa = r.rest_curvature.ravel()
        y = np.linalg.lstsq(jac.T, kappa, rcond=None)[0]
        assert np.linalg.norm(kappa - jac.T @ y) < 1e-5 * np.linalg.norm(kappa)


def test_tracking_slides_to_the_least_tension_in_few_iterations():
    """Along the tendon robot's circle every answer is the least tension that
    reaches its point (the free tensions in the row space of the tip's
    Jacobian), and the slide there takes few iterations: it converged
    linearly (8.8 a point) until the extrapolated slide and the predicted
    start (5.5), whose first step now already pulls toward the least tension
    (5.15). Those were the descent's steps, each a forward solve and the tip's
    Jacobian; tracking now takes coupled iterations (the equilibrium and the
    tensions stepped together, one linearisation each, cheaper than a
    descent step, then one solve): 5.35 a point (6.5 with the first step
    undamped, 8 without the extrapolation: the slide's ratio grows from 0.12
    to 0.24 a step while the state converges). From the equilibrium
    extrapolated along the path with the drive (up to fourth order), its
    first step undamped within 1 % of the length: 3.5."""
    example = Path(__file__).resolve().parent.parent / "examples" / "robots"
    robot = Robot.from_file(example / "tendon_robot.toml")
    points = softspine._core.trajectory_points("circle", 60, robot)
    results = robot.track(points, load=0.02)
    assert all(r.reached for r in results)
    assert np.mean([r.iterations for r in results]) <= 3.8
    for r in results[::6]:
        jac = robot.sensitivity(None, 0.02, "tensions", tensions=r.tensions).tip_position
        free = r.tensions > 1e-9
        t = r.tensions[free]
        y = np.linalg.lstsq(jac[:, free].T, t, rcond=None)[0]
        assert np.linalg.norm(t - jac[:, free].T @ y) < 1e-5 * np.linalg.norm(t)


def test_tracking_the_seed_s_trajectories_takes_two_linearisations_a_point():
    """Along a path the coupled iteration starts at the equilibrium and the
    drive extrapolated from the last answers (in the order that predicted the
    last answer best, up to fourth) and settles once the miss its last move
    leaves, falling with the square of the move, is within tol: two
    linearisations a point from the fifth point on, three or four after
    each corner of the pentagram (measured 2.27, 2.55 and 2.28 a point on the
    circle, pentagram and spiral; 4.2, 4.7 and 4.6 before, from the last
    equilibrium with the drive extrapolated linearly, on target before it
    settled). Each answer is still certified by a forward solve: reached,
    converged and stable, the tip within tol."""
    robot = Robot()
    for name, most, mean in [("circle", 2, 2.4), ("pentagram", 4, 2.7), ("spiral", 2, 2.45)]:
        points = softspine._core.trajectory_points(name, 60, robot)
        results = robot.track(points, load=0.03)
        iterations = [r.iterations for r in results]
        assert all(r.reached and r.solution.converged and r.solution.stable for r in results)
        assert max(r.tip_miss for r in results) <= 1e-9
        assert np.mean(iterations) <= mean, (name, iterations)
        assert max(iterations[4:]) <= most, (name, iterations)


def test_tol_means_the_same_angle_for_a_direction_on_every_drive():
    """One meaning of tol: the tip within tol of the point and its tangent
    within tol / L of the direction, whatever drives the robot."""
    example = Path(__file__).resolve().parent.parent / "examples" / "robots"
    cases = [(Robot(), 0.02, np.array([[0.4, -0.2], [0.3, 0.1]] * 5)),
             (Robot.from_file(example / "tendon_robot.toml"), 0.02, None)]
    for robot, load, kappa in cases:
        if kappa is None:
            sol = robot.forward(tensions=[6.0, 0, 0, 0, 5.0, 0, 0, 0, 4.0], load=load)
        else:
            sol = robot.forward(kappa, load=load)
        tangent = sol.rotation_matrices[-1][:, 2]
        tol = 1e-6
        r = robot.inverse(sol.tip_position, load=load, direction=tangent, tol=tol)
        assert r.ending == softspine.IkEnding.REACHED, r.message
        reached = r.solution.rotation_matrices[-1][:, 2]
        angle = np.arctan2(np.linalg.norm(np.cross(reached, tangent)), reached @ tangent)
        length = robot.to_dict()["length"]
        assert r.tip_miss <= tol and angle <= tol / length, (r.tip_miss, angle)


def test_a_full_pose_is_reached_on_every_drive_within_tol_over_l():
    """A full pose: the tip's point within tol and its frame within tol / L
    rad, given as a quaternion [w, x, y, z] or a scipy Rotation."""
    from scipy.spatial.transform import Rotation

    example = Path(__file__).resolve().parent.parent / "examples" / "robots"
    cases = [(Robot(), {"rest_curvature": np.array([[0.4, -0.2], [0.3, 0.1]] * 5)}),
             (Robot.from_file(example / "tendon_robot.toml"),
              {"tensions": [6.0, 0, 0, 0, 5.0, 0, 0, 0, 4.0]})]
    for robot, drive in cases:
        sol = robot.forward(load=0.02, **drive)
        w, x, y, z = sol.quaternions[-1]
        aimed = Rotation.from_quat([x, y, z, w])
        tol, length = 1e-7, robot.to_dict()["length"]
        for orientation in ([w, x, y, z], aimed):
            r = robot.inverse(sol.tip_position, load=0.02, orientation=orientation, tol=tol)
            assert r.ending == softspine.IkEnding.REACHED, r.message
            w2, x2, y2, z2 = r.solution.quaternions[-1]
            angle = (Rotation.from_quat([x2, y2, z2, w2]) * aimed.inv()).magnitude()
            assert r.tip_miss <= tol and angle <= tol / length, (r.tip_miss, angle)


@pytest.mark.parametrize(
    ("keywords", "message"),
    [({"orientation": [1, 0, 0, 0], "direction": [0, 0, -1]}, "^orientation: give a direction or"),
     ({"orientation": [0, 0, 0, 0]}, "^orientation: must be a finite non-zero quaternion"),
     ({"orientation": [1, 0, 0]}, "^orientation: expected a quaternion")],
)
def test_a_bad_orientation_is_refused_by_name(keywords, message):
    with pytest.raises(ValueError, match=message):
        Robot().inverse([0.1, 0.0, -0.9], load=0.02, **keywords)


def test_a_target_farther_than_the_robot_is_long_is_out_of_reach():
    r = Robot().inverse([1.0, 0.0, -1.0], load=0.03)
    assert not r.reached
    assert "out of reach" in r.message and "length range" not in r.message, r.message


def test_a_target_the_muscles_cannot_bend_to_says_so():
    """Within the backbone's length, but beyond what a 2.5 % contraction range bends."""
    robot = Robot({"muscle_length_range": [0.098, 0.1005]})
    r = robot.inverse([0.5, 0.0, -0.5], load=0.03)
    assert not r.reached and r.solution.stable
    assert "length range limits" in r.message, r.message
    assert robot.within_bounds(r.rest_curvature)


def test_running_out_of_iterations_says_so():
    r = Robot(UPRIGHT).inverse([0.3, 0.2, -0.3], load=0.08, max_iterations=1)
    assert not r.reached
    assert "max_iterations" in r.message, r.message


# --- robot input -------------------------------------------------------------


@pytest.mark.parametrize(
    "data,key",
    [
        ({"length": 1e-300}, "length"),
        ({"length": 1e300}, "length"),
        ({"muscle_radius": 1e-300}, "muscle_radius"),
        ({"muscle_radius": 1e300}, "muscle_radius"),
        ({"inflation_rate": 1e-320}, "inflation_rate"),
        ({"muscle_length_range": [1e-320, 1e-319]}, "muscle_length_range"),
        ({"muscle_rest_length": 1e-310}, "muscle_rest_length"),
        ({"linear_density": 1e308}, "linear_density"),
        ({"disk_mass": 1e308}, "disk_mass"),
        ({"muscle_angles": [0, 180, 360]}, "muscle_angles"),
        ({"muscle_angles": [10, 10, 100]}, "muscle_angles"),
        ({"sections": 2.5}, "sections"),
        ({"sections": 10_001}, "sections"),
        ({"n_elements": 2_000_000}, "n_elements"),
    ],
)
def test_robot_input_is_refused_naming_the_key(data, key):
    with pytest.raises(ValueError, match=f"^{key}:"):
        Robot(data)


def test_the_largest_counts_are_accepted():
    # The default n: the smallest multiple of the sections that is at least 20.
    assert Robot({"sections": 10_000}).n_elements == 10_000
    assert Robot({"sections": 1, "n_elements": 1_000_000}).n_elements == 1_000_000


@pytest.mark.parametrize(
    "data,key,shown",
    [
        ('{"sections": 1e19}', "sections", "1e19"),
        ("{'sections': 10**19}", "sections", "1e19"),
        ('{"sections": 1e12}', "sections", "1000000000000"),
        ('{"n_elements": 1e12}', "n_elements", "1000000000000"),
    ],
)
def test_huge_counts_are_refused_before_allocating(data, key, shown):
    out = run_isolated(
        f"""
        from softspine import Robot
        try:
            Robot({data}).inverse([0.1, 0.0, -0.9], load=0.03)
        except ValueError as e:
            print(e)
        """
    )
    assert out.returncode == 0, out.stderr
    message = out.stdout.strip()
    assert message.startswith(f"{key}:"), message
    assert message.endswith(f"got {shown}"), message


def test_the_ending_is_exposed_with_its_reason():
    robot = Robot()
    tip = robot.forward([[1.0, 0.5]] * robot.sections, load=0.03).tip_position
    ok = robot.inverse(tip, load=0.03)
    assert ok.reached and ok.ending == "reached" and ok.starts >= 1
    far = robot.inverse([0.0, 0.0, -2.0], load=0.03)
    assert not far.reached and far.ending == "out_of_reach"


def test_a_warm_solve_toward_a_reference_elsewhere_makes_no_coupled_attempt():
    """A warm start (an earlier answer) with a reference elsewhere starts
    the search at the reference, away from the warm equilibrium: the coupled
    iteration (which steps that equilibrium and the drive together) does not
    apply there. It was tried and failed after its 10 iterations before the
    descent's 15 (25 in all, twice the time)."""
    robot = Robot()
    points = softspine._core.trajectory_points("circle", 60, robot)
    before = robot.inverse(points[0], load=0.03)
    r = robot.inverse(points[1], load=0.03, initial=before, reference=np.zeros((10, 2)))
    assert r.reached, r.message
    assert r.iterations <= 15


def test_tracked_answers_with_a_direction_are_the_descents():
    """Tracking with a tip direction steps the tip's turn rows in the coupled
    iteration (three more adjoint solves): each answer equals the descent's
    from a new solver (no warm state, no coupled iteration) with the
    previous answer as reference, within the minimum-norm accuracy (measured
    6e-7 to 9e-7 of the drive)."""
    robot = Robot()
    points = softspine._core.trajectory_points("circle", 60, robot)[:6]
    direction = [0.3, 0.0, -1.0]
    tracked = robot.track(points, load=0.03, direction=direction)
    for k in range(1, len(points)):
        before, after = tracked[k - 1], tracked[k]
        alone = robot.inverse(points[k], load=0.03, direction=direction,
                              reference=before.rest_curvature)
        assert after.reached and alone.reached, (after.message, alone.message)
        a, b = after.rest_curvature.ravel(), alone.rest_curvature.ravel()
        assert np.linalg.norm(a - b) <= 1e-5 * np.linalg.norm(a)
