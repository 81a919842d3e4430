"""Batches on every core (`Robot.forward_batch`, `workspace`, `inverse_batch`,
`solve_batch`) and the reusable `Solver`: each checked against the one-by-one
solve it stands for."""

from __future__ import annotations

import pickle
import signal
import subprocess
import sys
import textwrap
import time

import numpy as np
import pytest

import softspine
from softspine.batch import BatchResult, concatenate

from isolated import run_isolated

LOAD = 0.03


@pytest.fixture(scope="module")
def robot() -> softspine.Robot:
    return softspine.Robot()


@pytest.fixture(scope="module")
def actuations(robot) -> np.ndarray:
    return robot.workspace(40, LOAD, seed=7).actuations


# --- forward -------------------------------------------------------------------


def test_a_forward_batch_is_the_one_by_one_forward_solve(robot, actuations):
    batch = robot.forward_batch(actuations, LOAD, warm_start=False, shapes=True)
    assert isinstance(batch, BatchResult) and len(batch) == len(actuations)
    for i, k in enumerate(actuations):
        one = robot.forward(k, LOAD)
        # The same solve, cold: the same bits.
        np.testing.assert_array_equal(batch.tip_positions[i], one.tip_position)
        np.testing.assert_array_equal(batch.positions[i], one.positions)
        np.testing.assert_array_equal(batch.quaternions[i], one.quaternions)
        assert batch.status[i] == one.status and batch.iterations[i] == one.iterations
    assert batch.converged.all() and batch.stable.all()
    np.testing.assert_array_equal(batch.actuations, actuations)


def test_warm_starts_along_a_path_land_on_the_same_equilibria(robot, actuations):
    path = np.linspace(actuations[0], actuations[1], 50)
    cold = robot.forward_batch(path, LOAD, warm_start=False)
    warm = robot.forward_batch(path, LOAD, warm_start=True)
    assert warm.converged.all()
    # Both certify their answer to the residual tolerance: the same
    # equilibrium to about 1e-10 m, and a warm start takes fewer iterations.
    assert np.abs(warm.tip_positions - cold.tip_positions).max() < 1e-9
    assert warm.iterations.sum() < cold.iterations.sum()


def test_the_answers_do_not_depend_on_the_number_of_threads(robot, actuations):
    one = robot.forward_batch(actuations, LOAD, threads=1, chunk=6)
    two = robot.forward_batch(actuations, LOAD, threads=2, chunk=6)
    for field in ("tip_positions", "tip_quaternions", "iterations", "residual_norms"):
        np.testing.assert_array_equal(getattr(one, field), getattr(two, field))


def test_a_batch_cut_at_chunk_boundaries_is_the_whole_batch(robot, actuations):
    whole = robot.forward_batch(actuations, LOAD, chunk=8)
    parts = [robot.forward_batch(actuations[i : i + 16], LOAD, chunk=8) for i in (0, 16, 32)]
    joined = concatenate(parts)
    for field, value in whole.to_dict().items():
        if value is None:
            assert getattr(joined, field) is None
        else:
            np.testing.assert_array_equal(getattr(joined, field), value)


def test_a_workspace_is_seeded_and_within_the_muscle_range(robot):
    a = robot.workspace(30, LOAD, seed=1)
    b = robot.workspace(30, LOAD, seed=1)
    c = robot.workspace(30, LOAD, seed=2)
    np.testing.assert_array_equal(a.actuations, b.actuations)
    np.testing.assert_array_equal(a.tip_positions, b.tip_positions)
    assert not np.array_equal(a.actuations, c.actuations)
    assert all(robot.within_bounds(k) for k in a.actuations)
    assert a.converged.all()


def test_batch_results_pickle_and_save(robot, actuations, tmp_path):
    batch = robot.forward_batch(actuations[:5], LOAD)
    again = pickle.loads(pickle.dumps(batch))
    np.testing.assert_array_equal(again.tip_positions, batch.tip_positions)
    path = tmp_path / "batch.npz"
    np.savez(path, **{k: v for k, v in batch.to_dict().items() if v is not None})
    with np.load(path) as saved:
        np.testing.assert_array_equal(saved["status"], batch.status)


def test_progress_is_reported_to_the_end(robot, actuations):
    calls = []
    robot.forward_batch(actuations, LOAD, progress=lambda done, total: calls.append((done, total)))
    assert calls and calls[-1] == (len(actuations), len(actuations))
    assert all(d <= t for d, t in calls)


def test_the_progress_bar_ends_once_with_its_rate(robot, actuations, capfd):
    # progress=True: tqdm's bar on standard error, from the start; one
    # 100 % line however often the end is reported (the hand-written bar
    # repeated it), with the rate.
    robot.forward_batch(actuations, LOAD, progress=True)
    lines = capfd.readouterr().err.replace("\r", "\n").splitlines()
    ends = [line for line in lines if line.startswith("100%")]
    total = len(actuations)
    assert len(ends) == 1 and f"| {total}/{total} [" in ends[0] and "solve/s" in ends[0], lines
    bar = softspine.batch.BarProgress(after=0.0, always=True)
    for _ in range(3):
        bar(total, total)
    assert capfd.readouterr().err.count("100%") == 1


def test_no_progress_bar_off_a_terminal_by_default(robot, actuations, capfd):
    robot.forward_batch(actuations, LOAD)
    robot.forward_batch(actuations, LOAD, progress=False)
    assert capfd.readouterr().err == ""


def test_an_exception_in_progress_stops_the_batch(robot, actuations):
    def fail(done, total):
        raise RuntimeError("stop here")

    with pytest.raises(RuntimeError, match="stop here"):
        robot.forward_batch(actuations, LOAD, progress=fail)


# --- inverse and scenes --------------------------------------------------------


def test_an_inverse_batch_reaches_reachable_targets(robot):
    reachable = robot.workspace(6, LOAD, seed=3)
    ik = robot.inverse_batch(reachable.tip_positions, LOAD, chunk=3)
    assert ik.reached.all(), ik.ending
    assert ik.tip_miss.max() < 1e-6
    # Each answer's forward solve puts the tip there.
    for i, k in enumerate(ik.rest_curvature):
        tip = robot.forward(k, LOAD).tip_position
        assert np.linalg.norm(tip - reachable.tip_positions[i]) < 1e-6


def test_solve_batch_solves_each_scene_as_solve_does():
    scenes = [
        {"length": 1, "stiffness": {"kx": 1, "ky": 1, "kz": 1}, "tip_force": [p, 0, 0]}
        for p in (0.5, 1.0, 3.0)
    ]
    batch = softspine.solve_batch(scenes, n_elements=30, shapes=True)
    for i, scene in enumerate(scenes):
        one = softspine.solve(scene, n_elements=30)
        np.testing.assert_array_equal(batch.positions[i], one.positions)
    assert batch.converged.all()


# --- bad input -------------------------------------------------------------------


@pytest.mark.parametrize(
    ("call", "message"),
    [
        (lambda r, k: r.forward_batch(k[:, :3]), r"actuations: expected shape \(samples, 10, 2\)"),
        (lambda r, k: r.forward_batch("abc"), "actuations"),
        (lambda r, k: r.forward_batch(k, chunk=0), "chunk"),
        (lambda r, k: r.forward_batch(k, threads=0), "threads"),
        (lambda r, k: r.forward_batch(k, load=-1.0), "load"),
        (lambda r, k: r.inverse_batch([[0, 0, np.nan]]), "targets"),
        (lambda r, k: r.workspace(-3), "samples"),
        (lambda r, k: softspine.solve_batch([{"length": -1}]), r"scenes\[0\]"),
        (lambda r, k: softspine.solve_batch(3), "scenes"),
    ],
)
def test_bad_batches_are_refused_by_name(robot, actuations, call, message):
    with pytest.raises(ValueError, match=message):
        call(robot, actuations)


TENDON_ROBOT = "examples/robots/tendon_robot.toml"
CATHETER = "examples/robots/magnetic_catheter.toml"


@pytest.mark.parametrize(
    "call",
    [
        "Robot().workspace(10**12, progress=False)",
        f"Robot.from_file({TENDON_ROBOT!r}).workspace(10**12, progress=False)",
        f"Robot.from_file({CATHETER!r}).workspace(10**12, progress=False)",
        "Robot().workspace(10**12, progress=False, executor=ThreadPoolExecutor(1), part=64)",
    ],
)
def test_a_batch_too_large_for_memory_is_refused_before_allocating(call):
    # On 3e30b16 the interpreter aborted allocating 8 TB of sample indices.
    out = run_isolated(
        f"""
        from concurrent.futures import ThreadPoolExecutor
        from softspine import Robot
        try:
            {call}
        except ValueError as e:
            print(e)
        """
    )
    assert out.returncode == 0, out.stderr
    assert out.stdout.startswith("samples: 1000000000000 samples need"), out.stdout
    assert "free on this machine" in out.stdout


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="RLIMIT_AS and /proc")
def test_a_batch_whose_results_fail_to_allocate_raises_memory_error():
    # The results fit the machine's free memory but not the address space
    # left to the process: the core's allocation fails, before any solve.
    out = run_isolated(
        """
        import resource, softspine
        robot = softspine.Robot()
        robot.workspace(2, progress=False)
        used = int(open("/proc/self/statm").read().split()[0]) * resource.getpagesize()
        resource.setrlimit(resource.RLIMIT_AS, (used + 2**29, resource.RLIM_INFINITY))
        try:
            robot.workspace(5_000_000, progress=False)
        except MemoryError as e:
            print("MemoryError", e)
        """
    )
    assert out.returncode == 0, out.stderr
    assert out.stdout.startswith("MemoryError samples: the results: out of memory"), out.stdout


@pytest.mark.parametrize("threads", [2000, 10**6])
def test_thread_counts_beyond_the_cores_are_refused(threads):
    # 2000 threads drove the load average above 600; 10**6 ran for minutes.
    out = run_isolated(
        f"""
        from softspine import Robot
        try:
            Robot().workspace(4, threads={threads}, progress=False)
        except ValueError as e:
            print(e)
        """,
        timeout=60,
    )
    assert out.returncode == 0, out.stderr
    assert out.stdout.startswith(f"threads: {threads} is more than "), out.stdout
    most = int(out.stdout.split()[5])
    assert len(softspine.Robot().workspace(4, threads=most, progress=False)) == 4


def test_workspace_indices_past_the_last_are_refused(robot):
    with pytest.raises(ValueError, match="^first: "):
        robot.workspace(4, first=2**64 - 2, progress=False)


def test_a_non_finite_actuation_names_its_sample(robot, actuations):
    bad = actuations.copy()
    bad[3, 2, 1] = np.inf
    with pytest.raises(ValueError, match="sample 3"):
        robot.forward_batch(bad, LOAD)


@pytest.mark.slow
def test_ctrl_c_interrupts_a_long_batch():
    code = textwrap.dedent(
        """
        import signal, sys, time, softspine
        signal.signal(signal.SIGINT, signal.default_int_handler)
        robot = softspine.Robot()
        print("ready", flush=True)
        try:
            robot.workspace(10_000_000, 0.03, progress=False)
            print("finished")
        except KeyboardInterrupt:
            print("interrupted", time.perf_counter(), flush=True)
        """
    )
    proc = subprocess.Popen(
        [sys.executable, "-c", code], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
    )
    assert proc.stdout.readline().strip() == "ready"
    time.sleep(1.0)
    sent = time.perf_counter()
    proc.send_signal(signal.SIGINT)
    out, err = proc.communicate(timeout=60)
    assert out.startswith("interrupted"), (out, err)
    # The poll runs every 20 ms and a sample takes tens of microseconds.
    assert float(out.split()[1]) - sent < 0.25


# --- the reusable solver ---------------------------------------------------------


def test_a_solver_solves_as_solve_does_and_starts_warm(robot, actuations):
    solver = softspine.Solver(robot.scene(actuations[0], LOAD), n_elements=20)
    first = solver.solve()
    np.testing.assert_array_equal(
        first.positions, softspine.solve(robot.scene(actuations[0], LOAD), n_elements=20).positions
    )
    # A small change of the actuation: warm from the last equilibrium.
    nearby = actuations[0] * 1.002
    solver.set_rest_curvature(nearby)
    warm = solver.solve()
    cold = solver.solve(warm=False)
    assert warm.iterations < cold.iterations
    assert np.abs(warm.positions - cold.positions).max() < 1e-9
    assert np.abs(cold.positions - robot.forward(nearby, LOAD).positions).max() < 1e-12


def test_a_solver_takes_new_tip_loads(robot, actuations):
    scene = robot.scene(actuations[1], LOAD)
    solver = softspine.Solver(scene, n_elements=20)
    solver.solve()
    solver.set_tip_force([0.2, 0.0, -0.5])
    solver.set_tip_moment([0.0, 0.05, 0.0])
    moved = solver.solve(check=True)
    data = scene.to_dict()
    data["tip_force"] = [0.2, 0.0, -0.5]
    data["tip_moment"] = [0.0, 0.05, 0.0]
    fresh = softspine.solve(data, n_elements=20)
    assert np.abs(moved.positions - fresh.positions).max() < 1e-9
    np.testing.assert_array_equal(solver.tip_force, [0.2, 0.0, -0.5])
    np.testing.assert_array_equal(solver.scene.to_dict()["tip_moment"], [0.0, 0.05, 0.0])


def test_a_solver_refuses_bad_input_by_name(robot):
    solver = softspine.Solver(robot.scene(np.zeros((10, 2))), n_elements=20)
    with pytest.raises(ValueError, match=r"force: at \[2\]: must be finite"):
        solver.set_tip_force([0, 0, np.nan])
    with pytest.raises(ValueError, match="rest_curvature"):
        solver.set_rest_curvature(np.zeros((3, 2)))
    # One row turned the ten sections into one, and the solve went on (3e30b16).
    with pytest.raises(ValueError, match=r"^rest_curvature: expected one row a section .*\(10\)"):
        solver.set_rest_curvature([[1.0, 2.0]])
    with pytest.raises(ValueError, match="^rest_curvature: expected 10 sections, got 1"):
        robot.muscle_lengths([[1.0, 2.0]])
    with pytest.raises(ValueError, match="initial"):
        solver.solve("last")
    with pytest.raises(ValueError, match="initial"):
        solver.solve(np.ones((5, 4)))
    # Still usable after the refusals.
    assert solver.solve().converged


def test_robot_forward_takes_a_warm_start(robot, actuations):
    cold = robot.forward(actuations[2], LOAD)
    nearby = actuations[2] * 0.998
    warm = robot.forward(nearby, LOAD, initial=cold)
    again = robot.forward(nearby, LOAD, initial=cold.quaternions)
    assert warm.iterations < robot.forward(nearby, LOAD).iterations
    np.testing.assert_array_equal(warm.positions, again.positions)


def test_robot_inverse_takes_a_warm_start(robot, actuations):
    targets = [robot.forward(k, LOAD).tip_position for k in (actuations[3], actuations[3] * 1.01)]
    first = robot.inverse(targets[0], LOAD)
    cold = robot.inverse(targets[1], LOAD)
    warm = robot.inverse(targets[1], LOAD, initial=first)
    assert first.reached and cold.reached and warm.reached
    assert warm.iterations < cold.iterations
    # From the equilibrium alone (quaternions), with the reference given.
    again = robot.inverse(
        targets[1], LOAD, reference=first.rest_curvature, initial=first.solution.quaternions
    )
    assert again.reached
    with pytest.raises(ValueError, match="initial: has 5 nodes"):
        robot.inverse(targets[1], LOAD, initial=np.tile([1.0, 0, 0, 0], (5, 1)))
