"""What a Solution and an IkResult give a user: arc length, moments, curvatures,
rotation matrices, the status enums, to_dict / from_dict, pickling (for
multiprocessing and distributed engines) and Python-style reprs."""

from __future__ import annotations

import inspect
import json
import pickle
import subprocess
import sys
from concurrent.futures import ProcessPoolExecutor
from multiprocessing import get_context

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import softspine
from softspine import IkEnding, Scheme, Status

UNIT = {"kx": 1.0, "ky": 1.0, "kz": 1.0}


def loaded_cantilever(force=(3.0, 0.0, 0.0), moment=(0.0, 0.5, 0.0)):
    return {"length": 1.0, "stiffness": UNIT, "tip_force": list(force), "tip_moment": list(moment)}


def load_moment_about_nodes(sol, force, moment):
    """The continuous rod's internal moment at each node from the balance of the
    part beyond it, (r_tip - r_j) x P + M, at the solved positions: independent
    of how the solver forms its moments."""
    r = sol.positions
    return np.cross(r[-1] - r, np.asarray(force)) + np.asarray(moment)


def test_moments_balance_the_loads_beyond_each_node_to_second_order():
    force, moment = (3.0, 0.0, -1.0), (0.2, 0.5, 0.1)
    errors = []
    for n in (40, 80, 160):
        sol = softspine.solve(loaded_cantilever(force, moment), n_elements=n, check=True)
        assert sol.moments.shape == (n + 1, 3)
        exact = load_moment_about_nodes(sol, force, moment)
        # The tip is the boundary condition itself.
        assert np.allclose(sol.moments[-1], moment, atol=1e-12)
        errors.append(np.abs(sol.moments - exact).max())
    assert errors[-1] < 1e-4
    orders = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
    assert np.all(orders > 1.8), (errors, orders)


def test_moments_of_a_clamped_rod_balance_its_reactions():
    """Clamped tip: the tip carries the clamp's force and moment; the moment at
    every node balances them, as the applied loads of a free rod."""
    clamp = {"type": "clamped", "position": [0.4, 0.1, 0.8],
             "quaternion": Rotation.from_euler("y", 40, degrees=True).as_quat()[[3, 0, 1, 2]]}
    errors = []
    for n in (40, 80):
        sol = softspine.solve({"length": 1.0, "stiffness": UNIT, "tip": clamp}, n_elements=n,
                              check=True)
        force, moment = sol.tip_reaction_force, sol.tip_reaction_moment
        assert np.abs(moment).max() > 0.1
        assert np.allclose(sol.moments[-1], moment, atol=1e-12)
        errors.append(np.abs(sol.moments - load_moment_about_nodes(sol, force, moment)).max())
    assert errors[1] < errors[0] / 3.5 and errors[1] < 2e-3 * np.abs(moment).max(), errors


def test_base_moment_under_gravity_is_the_weight_moment():
    """A horizontal cantilever under its own weight q: the support carries
    q x_c L about the base, x_c the centroid's reach, to second order."""
    scene = {
        "length": 1.0,
        "stiffness": UNIT,
        "base_quaternion": Rotation.from_euler("y", 90, degrees=True).as_quat()[[3, 0, 1, 2]],
        "gravity": {"linear_density": 0.1, "vector": [0.0, 0.0, -9.81]},
    }
    sol = softspine.solve(scene, n_elements=200, check=True)
    q = np.array([0.0, 0.0, -0.981])
    mid = 0.5 * (sol.positions[1:] + sol.positions[:-1])
    exact = np.cross(mid - sol.positions[0], q).sum(axis=0) / 200
    assert np.allclose(sol.moments[0], exact, atol=1e-5 * np.abs(exact).max())


def test_a_pure_moment_is_transmitted_exactly_by_every_element():
    """A tip moment M alone bends the discrete rod into an arc whose elements
    turn by theta = asin(ds M / EI) (the node balance (2/ds) sin(theta/2)
    cos(theta/2) EI = M): its discrete curvature (2/ds) sin(theta/2) is M/EI
    to second order, and the moment every element transmits is M exactly."""
    m, k, n = 0.7, 2.0, 30
    scene = {"length": 1.0, "stiffness": {"kx": k, "ky": k, "kz": 1.0}, "tip_moment": [0, m, 0]}
    sol = softspine.solve(scene, n_elements=n, check=True)
    assert sol.curvatures.shape == (n, 3)
    theta = np.arcsin(m / k / n)
    assert np.allclose(sol.curvatures, [0.0, 2 * n * np.sin(theta / 2), 0.0], atol=1e-12)
    assert np.allclose(sol.moments, [0.0, m, 0.0], atol=1e-12)


def test_rotation_matrices_are_the_quaternions_and_arc_length_the_nodes():
    sol = softspine.solve(loaded_cantilever(), n_elements=20, check=True)
    R = sol.rotation_matrices
    assert R.shape == (21, 3, 3)
    scipy_R = Rotation.from_quat(sol.quaternions[:, [1, 2, 3, 0]]).as_matrix()
    assert np.allclose(R, scipy_R, atol=1e-12)
    assert np.allclose(sol.arc_length, np.linspace(0.0, 1.0, 21), atol=1e-15)
    assert sol.length == 1.0
    # The tangent (third column) follows the backbone: each chord lies
    # between its two nodes' tangents.
    chords = np.diff(sol.positions, axis=0) * 20
    assert np.allclose(chords, 0.5 * (R[:-1, :, 2] + R[1:, :, 2]), atol=1e-2)


def test_status_is_the_exported_enum_that_equals_its_name():
    sol = softspine.solve(loaded_cantilever(), n_elements=20)
    assert sol.status is Status.CONVERGED
    assert sol.status == "converged" and f"{sol.status}" == "converged"
    limited = softspine.solve(loaded_cantilever((30.0, 0, 0)), n_elements=20, max_iterations=1)
    assert limited.status is Status.ITERATION_LIMIT and not limited.converged


def test_the_enums_are_the_cores_str_enums_with_its_docs():
    # Generated from the core at import: every member carries the core's
    # description, and a member is a str that serialises and pickles as such.
    for enum in (Status, IkEnding, Scheme):
        assert enum.__module__ == "softspine" and enum.__doc__
        docs = [member.__doc__ for member in enum]
        assert all(docs) and len(set(docs)) == len(docs) and enum.__doc__ not in docs
        for member in enum:
            assert isinstance(member, str) and str(member) == member.value
            assert enum(member.value) is member
            assert pickle.loads(pickle.dumps(member)) is member
    assert [s.value for s in Scheme] == ["fd2", "fe4", "rk4"]
    assert "residual_tol" in Status.CONVERGED.__doc__
    assert json.dumps({"status": Status.CONVERGED}) == '{"status": "converged"}'


def test_reprs_use_python_booleans():
    sol = softspine.solve(loaded_cantilever(), n_elements=20)
    assert "stable=True" in repr(sol)
    ik = softspine.Robot().inverse([0.3, 0.0, -0.8], load=0.03)
    assert ik.ending is IkEnding.REACHED
    assert "reached=True" in repr(ik)


def test_solution_round_trips_through_to_dict_and_pickle():
    pinned = {"type": "pinned", "position": [0.5, 0.0, 0.7]}
    sol = softspine.solve({**loaded_cantilever(), "tip": pinned}, n_elements=24)
    assert sol.converged and sol.tip_reaction_force is not None
    assert sol.solve_time > 0.0
    for copy in (softspine.Solution.from_dict(sol.to_dict()), pickle.loads(pickle.dumps(sol))):
        for key, value in sol.to_dict().items():
            other = copy.to_dict()[key]
            if isinstance(value, np.ndarray):
                assert np.array_equal(value, other), key
            else:
                assert value == other, key
        assert copy.status is sol.status and repr(copy) == repr(sol)
        assert np.array_equal(copy.moments, sol.moments)
        assert np.array_equal(copy.curvatures, sol.curvatures)


def test_a_converged_solution_with_a_nan_reaction_is_refused():
    pinned = {"type": "pinned", "position": [0.5, 0.0, 0.7]}
    d = softspine.solve({**loaded_cantilever(), "tip": pinned}, n_elements=24).to_dict()
    d["tip_reaction_force"][1] = np.nan
    with pytest.raises(ValueError, match="^solution.tip_reaction_force: .* got NaN"):
        softspine.Solution.from_dict(d)
    d["status"] = "not_converged"
    assert np.isnan(softspine.Solution.from_dict(d).tip_reaction_force[1])


def test_an_ik_result_with_an_unknown_key_is_refused():
    d = softspine.Robot().inverse([0.05, 0.0, -0.9], load=0.03).to_dict()
    d["spare"] = 1
    with pytest.raises(ValueError, match="^ik_result: unknown key 'spare'"):
        softspine.IkResult.from_dict(d)


def test_a_failed_state_with_non_finite_values_still_pickles():
    d = softspine.solve(loaded_cantilever(), n_elements=10).to_dict()
    d["positions"][3] = np.nan
    d["residual_norm"] = float("inf")
    d["status"] = "numerical_error"
    copy = pickle.loads(pickle.dumps(softspine.Solution.from_dict(d)))
    assert copy.status is Status.NUMERICAL_ERROR and np.isnan(copy.positions[3]).all()


@pytest.mark.parametrize(
    ("change", "message"),
    [
        (lambda d: d.pop("stiffness"), "solution.stiffness: missing"),
        (lambda d: d.update(forces=d["forces"][:-1]), "solution.forces: has 10 rows"),
        (lambda d: d.update(rest_curvature=[[1, 0]] * 3),
         "solution.rest_curvature: 3 sections do not divide"),
        (lambda d: d.update(status="fine"), "status: unknown status 'fine'"),
        (lambda d: d.update(stable=1), "solution.stable: expected a bool"),
        # Accepted as a converged solution on 3e30b16:
        (lambda d: d.update(spare=1), "solution: unknown key 'spare'"),
        (lambda d: d["positions"].__setitem__((4, 1), np.nan),
         r"solution.positions\[4\]: a converged solution is finite, got NaN"),
        (lambda d: d.update(energy=float("inf")),
         "solution.energy: a converged solution is finite, got inf"),
        (lambda d: d["quaternions"].__setitem__(2, [0.5, 0, 0, 0]),
         r"solution.quaternions\[2\]: a converged solution has unit quaternions"),
    ],
)
def test_from_dict_names_a_bad_field(change, message):
    d = softspine.solve(loaded_cantilever(), n_elements=10).to_dict()
    change(d)
    with pytest.raises(ValueError, match=message):
        softspine.Solution.from_dict(d)


def test_scene_robot_and_ik_result_pickle():
    scene = softspine.Scene({**loaded_cantilever(), "name": "c", "base_position": [1, 2, 3]})
    assert pickle.loads(pickle.dumps(scene)).to_dict() == scene.to_dict()
    robot = softspine.Robot({"sections": 3, "length": 0.6})
    assert pickle.loads(pickle.dumps(robot)).to_dict() == robot.to_dict()
    ik = robot.inverse([0.1, 0.0, 0.55])
    copy = pickle.loads(pickle.dumps(ik))
    assert copy.ending is ik.ending and np.array_equal(copy.rest_curvature, ik.rest_curvature)
    assert np.array_equal(copy.solution.positions, ik.solution.positions)


def _tip_of(scene):
    return softspine.solve(scene, n_elements=20)


def test_solves_run_in_worker_processes():
    """multiprocessing pickles the arguments and the results both ways."""
    scenes = [softspine.Scene(loaded_cantilever((p, 0.0, 0.0))) for p in (1.0, 2.0)]
    with ProcessPoolExecutor(2, mp_context=get_context("spawn")) as pool:
        results = list(pool.map(_tip_of, scenes))
    for scene, sol in zip(scenes, results, strict=True):
        assert np.array_equal(sol.positions, _tip_of(scene).positions)


def test_help_shows_the_constructors_signatures():
    assert str(inspect.signature(softspine.Robot)) == "(data=None)"
    assert str(inspect.signature(softspine.Scene)) == "(data)"
    out = subprocess.run(
        [sys.executable, "-c", "import softspine; help(softspine.Robot)"],
        capture_output=True, text=True, check=True,
    ).stdout
    assert "Robot(data=None)" in out


@pytest.mark.parametrize("cls", [softspine.Scene, softspine.Solution, softspine.Robot,
                                 softspine.IkResult, softspine.InverseSolver,
                                 softspine.Settings, softspine.PaperSettings,
                                 softspine.Accuracy, softspine.IkSettings])
def test_every_public_property_and_method_has_a_docstring(cls):
    assert (cls.__doc__ or "").strip()
    missing = [
        name for name, member in vars(cls).items()
        if not name.startswith("_") and not (getattr(member, "__doc__", None) or "").strip()
    ]
    assert not missing, f"{cls.__name__}: {missing}"


@pytest.mark.parametrize("suffix", [".npz", ".json"])
def test_a_solution_is_saved_and_loaded_exactly(tmp_path, suffix):
    # A solution with contacts, friction and fields that are None: every
    # field of to_dict() comes back equal (issue 29, item 3).
    import math
    along_x = [math.sqrt(0.5), 0.0, math.sqrt(0.5), 0.0]
    floor = {"shape": "half_space", "point": [0, 0, -0.7080206], "normal": [0, 0, 1],
             "friction": 0.02}
    scene = {"length": 1.0, "stiffness": {"kx": 1.0, "ky": 1.0, "kz": 1.0},
             "base_quaternion": along_x, "rest_curvature": [[0.0, 2.0]],
             "gravity": {"linear_density": 1.0, "vector": [0, 0, -1.0]}, "obstacles": [floor]}
    sol = softspine.solve(scene, n_elements=40)
    assert len(sol.contacts["force"]) == 1 and sol.tip_reaction_force is None
    path = tmp_path / f"solution{suffix}"
    sol.save(path)
    again = softspine.Solution.load(path)
    a, b = sol.to_dict(), again.to_dict()
    assert a.keys() == b.keys()
    for key, value in a.items():
        if isinstance(value, np.ndarray):
            np.testing.assert_array_equal(b[key], value, err_msg=key)
        else:
            assert b[key] == value, key


def assert_same_fields(a: dict, b: dict, path: str = "") -> None:
    """Every field equal (arrays bit for bit, dtypes too), nested dicts too."""
    assert a.keys() == b.keys(), path
    for key, value in a.items():
        if isinstance(value, dict):
            assert_same_fields(value, b[key], f"{path}{key}.")
        elif isinstance(value, np.ndarray):
            np.testing.assert_array_equal(b[key], value, err_msg=path + key)
            assert b[key].dtype == value.dtype, path + key
        else:
            assert b[key] == value, path + key


@pytest.fixture(scope="module")
def tendon_robot() -> softspine.Robot:
    return softspine.Robot.from_file("examples/robots/tendon_robot.toml")


@pytest.mark.parametrize("suffix", [".npz", ".json"])
def test_an_inverse_result_is_saved_and_loaded_exactly(tmp_path, suffix, tendon_robot):
    # Its dict nests its solution's: NPZ keeps that under "solution/...".
    ik = tendon_robot.inverse([0.05, 0.02, 0.27], load=0.02)
    path = tmp_path / f"ik{suffix}"
    ik.save(path)
    again = softspine.IkResult.load(path)
    assert isinstance(again, softspine.IkResult) and again.ending == ik.ending
    assert_same_fields(ik.to_dict(), again.to_dict())


@pytest.mark.parametrize("suffix", [".npz", ".json"])
def test_batch_results_are_saved_and_loaded_exactly(tmp_path, suffix, tendon_robot):
    rng = np.random.default_rng(3)
    forward = tendon_robot.forward_batch(tensions=rng.uniform(0, 5, (4, 9)), shapes=True,
                                         load=0.01)
    targets = forward.tip_positions[:2]
    inverse = tendon_robot.inverse_batch(targets, load=0.01)
    for result in (forward, inverse):
        path = tmp_path / f"{type(result).__name__}{suffix}"
        result.save(path)
        again = type(result).load(path)
        assert type(again) is type(result)
        assert_same_fields(result.to_dict(), again.to_dict())
    assert forward.positions is not None and forward.field is None


def test_a_batch_result_from_a_bad_dict_is_refused_by_name(tendon_robot):
    result = tendon_robot.forward_batch(tensions=np.zeros((2, 9)))
    fields = result.to_dict()
    with pytest.raises(ValueError, match=r"BatchResult\.tip_position: unknown field"):
        softspine.BatchResult.from_dict({**fields, "tip_position": fields["tip_positions"]})
    del fields["status"]
    with pytest.raises(ValueError, match=r"BatchResult\.status: missing"):
        softspine.BatchResult.from_dict(fields)


def test_every_result_is_json_text_and_back(tendon_robot):
    # json.dumps(sol.to_dict()) cannot write NumPy arrays (issue 29, item 3):
    # to_json() is that dict as JSON text, from_json reads it back exactly.
    sol = tendon_robot.forward(tensions=np.full(9, 2.0), load=0.01)
    ik = tendon_robot.inverse(sol.tip_position, load=0.01)
    batch = tendon_robot.forward_batch(tensions=np.full((2, 9), 1.0), shapes=True)
    for result in (sol, ik, batch):
        text = result.to_json()
        assert isinstance(json.loads(text), dict)
        again = type(result).from_json(text)
        assert_same_fields(result.to_dict(), again.to_dict())
    with pytest.raises(ValueError, match="text: expected a JSON object, got list"):
        softspine.Solution.from_json("[1, 2]")
    with pytest.raises(TypeError, match="text: expected a JSON string, got dict"):
        softspine.Solution.from_json(sol.to_dict())


def test_a_solution_file_needs_a_known_suffix(tmp_path):
    sol = softspine.solve({"length": 1.0, "stiffness": {"kx": 1.0, "ky": 1.0, "kz": 1.0}})
    with pytest.raises(ValueError, match=r"path: expected a file ending in \.npz or \.json"):
        sol.save(tmp_path / "solution.txt")
    with pytest.raises(ValueError, match="path: expected"):
        softspine.Solution.load(tmp_path / "solution.csv")


def test_a_warm_start_brings_its_own_n():
    # The guide's "Solving" block: a solution of accuracy on demand (at the n
    # it chose) warm-starts the next solve without n_elements (issue 29,
    # item 7; it raised "initial: has 17 nodes, the discretisation has 21").
    scene = {"length": 1.0, "stiffness": {"kx": 1.0, "ky": 1.0, "kz": 1.0},
             "rest_curvature": [[1.0, 0.0], [0.0, 1.0], [1.0, 1.0]], "tip_force": [0.5, 0, 0]}
    chosen = softspine.solve(scene, tol=1e-4)
    assert chosen.n_elements != 21
    warm = softspine.solve(scene, initial=chosen)
    assert warm.converged and warm.n_elements == chosen.n_elements
    assert warm.iterations <= 2
    cold = softspine.solve(scene, n_elements=chosen.n_elements, scheme=warm.scheme.value)
    np.testing.assert_allclose(warm.positions, cold.positions, atol=1e-12)
    # Given both, they must agree; an n the sections do not divide is
    # refused naming the warm start.
    with pytest.raises(ValueError, match="initial: has"):
        softspine.solve(scene, initial=chosen, n_elements=chosen.n_elements + 3)
    with pytest.raises(ValueError, match=r"initial: has 5 nodes, 4 elements: must be a "
                                         r"positive multiple of the number of sections \(3\)"):
        softspine.solve(scene, initial=np.tile([1.0, 0, 0, 0], (5, 1)))
