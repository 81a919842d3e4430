"""Input reliability: NumPy scalars of every kind, deep or self-containing input,
numbers beyond a double, duplicate JSON keys, exact JSON numbers, refusals that
name the field or argument, the command line's user errors, and an InverseSolver
shared between threads.

Inputs that used to crash the process run in a subprocess, so that a crash fails
one test instead of killing pytest."""

from __future__ import annotations

import json
import math
import random
import re
import struct
import subprocess
import sys
import threading
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest

import softspine
from softspine import Robot, Scene, trajectories
from softspine._core import residual

GOOD = {"length": 1.0, "stiffness": {"kx": 1.0, "ky": 1.0, "kz": 1.0}}

PRELUDE = f"""
import numpy as np
import softspine
from softspine import Robot, Scene
from softspine._core import residual
GOOD = {GOOD!r}
deep = []
for _ in range(30_000):
    deep = [deep]
"""


def run(code: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-c", PRELUDE + code], capture_output=True, text=True, timeout=300
    )


def exception_line(stderr: str) -> str:
    """The line of the traceback that names the exception (notes may follow it)."""
    lines = [ln for ln in stderr.splitlines() if re.match(r"^\w+(Error|Exception): ", ln)]
    return lines[-1] if lines else ""


# --- Inputs that crashed the process (segfault): now accepted ---------------------


@pytest.mark.parametrize(
    "code,printed",
    [
        ("print(Scene({**GOOD, 'length': np.longdouble('0.5')}).length)", "0.5"),
        ("print(Scene({**GOOD, 'length': np.array(np.longdouble(2))}).length)", "2.0"),
        (
            "s = Scene({**GOOD, 'tip_force': np.array([1, 2, 3], dtype=np.longdouble)})\n"
            "print(s.to_dict()['tip_force'])",
            "[1.0, 2.0, 3.0]",
        ),
        (
            "s = Scene({**GOOD, 'length': np.float32(0.5), 'tip_force': [np.int64(1), 0, 0]})\n"
            "print(s.length, s.to_dict()['tip_force'])",
            "0.5 [1.0, 0.0, 0.0]",
        ),
        ("print(Robot({'length': np.longdouble('0.8')}).length)", "0.8"),
        (
            "k = Robot().muscle_lengths(np.zeros((10, 2), dtype=np.longdouble))\n"
            "print(k.shape)",
            "(10, 3)",
        ),
        (
            "r = Robot().inverse(np.array([0.1, 0.0, -0.9], dtype=np.longdouble))\n"
            "print(r.reached)",
            "True",
        ),
        (
            "q = np.zeros((21, 4), dtype=np.longdouble)\nq[:, 0] = 1\n"
            "print(residual(GOOD, q).shape)",
            "(20, 3)",
        ),
    ],
)
def test_longdouble_and_numpy_scalars_are_read(code, printed):
    p = run(code)
    assert p.returncode == 0, p.stderr[-3000:]
    assert p.stdout.strip() == printed


# --- Inputs that crashed the process: now refused, naming the field ---------------

NESTED = r"(\[0\])+: nested deeper than 32 levels"


@pytest.mark.parametrize(
    "code,message",
    [
        (
            "Scene({**GOOD, 'length': np.longdouble('1e400')})",
            r"ValueError: length: 1e\+400 is out of the range of a double",
        ),
        (
            "Robot({'disk_mass': np.longdouble('-1e4000')})",
            r"ValueError: disk_mass: -1e\+4000 is out of the range of a double",
        ),
        (
            "Robot().inverse(np.array(['0.1', '1e400', '-0.9'], dtype=np.longdouble))",
            r"ValueError: target: at \[1\]: 1e\+400 is out of the range of a double",
        ),
        ("Scene({**GOOD, 'tip_force': deep})", r"ValueError: tip_force" + NESTED),
        ("Robot({'gravity': deep})", r"ValueError: gravity" + NESTED),
        ("Robot().muscle_lengths(deep)", r"ValueError: rest_curvature: at " + NESTED),
        ("Robot().inverse(deep)", r"ValueError: target: at " + NESTED),
        ("residual(GOOD, deep)", r"ValueError: quaternions: at " + NESTED),
        (
            "loop = [0.0, 0.0]\nloop.append(loop)\nScene({**GOOD, 'tip_force': loop})",
            r"ValueError: tip_force(\[2\])+: nested deeper than 32 levels",
        ),
        (
            "scene = dict(GOOD)\nscene['tip'] = scene\nScene(scene)",
            r"ValueError: tip(\.tip)+\.stiffness: nested deeper than 32 levels",
        ),
        (
            "a = np.empty(2, dtype=object)\na[0] = a\na[1] = 1.0\nRobot().inverse(a)",
            r"ValueError: target: at " + NESTED,
        ),
        (
            "Scene({**GOOD, 'tip_force': np.array([1.0, None, 'x'], dtype=object)})",
            r"ValueError: tip_force\[1\]: expected a number, got null",
        ),
        (
            "Robot().inverse(np.array([0.1, None, -0.9], dtype=object))",
            r"ValueError: target: at \[1\]: expected a number, got null",
        ),
        (
            "Robot().muscle_lengths([[0, 0]] * 9 + [[0, [1]]])",
            r"ValueError: rest_curvature: at \[9\]\[1\]: expected a number, got a list",
        ),
        (
            "Scene({**GOOD, 'length': np.complex128(1)})",
            r"ValueError: length: unsupported value of type complex128",
        ),
    ],
)
def test_crashing_inputs_are_refused_by_field(code, message):
    p = run(code)
    assert p.returncode == 1, (p.returncode, p.stderr[-3000:])
    assert re.fullmatch(message, exception_line(p.stderr)), p.stderr[-3000:]


# --- Numbers beyond a double or an integer type ------------------------------------

HUGE = 10**400


@pytest.mark.parametrize(
    "scene,key",
    [
        ({**GOOD, "length": HUGE}, "length"),
        ({**GOOD, "stiffness": {"kx": 1, "ky": HUGE, "kz": 1}}, "stiffness.ky"),
        ({**GOOD, "tip_force": [0, HUGE, 0]}, r"tip_force\[1\]"),
        ({**GOOD, "length": np.array([HUGE], dtype=object)[0]}, "length"),
    ],
)
def test_huge_integers_in_a_scene_name_the_key(scene, key):
    with pytest.raises(ValueError, match=f"^{key}: integer too large for a double"):
        Scene(scene)


@pytest.mark.parametrize("key", ["length", "sections", "n_elements", "disk_mass"])
def test_huge_integers_in_a_robot_name_the_key(key):
    with pytest.raises(ValueError, match=f"^{key}: integer too large for a double"):
        Robot({key: HUGE})


@pytest.fixture(scope="module")
def robot():
    return Robot()


TARGET = [0.1, 0.0, -0.9]
ZERO = np.zeros((10, 2))


@pytest.mark.parametrize(
    "call,message",
    [
        (lambda r: r.inverse(TARGET, load=HUGE), "load: integer too large"),
        (lambda r: r.inverse(TARGET, load=[0.03]), "load: expected a mass [kg] or a dict"),
        (lambda r: r.inverse(TARGET, load="heavy"), "load: expected a mass [kg] or a dict"),
        (lambda r: r.forward(ZERO, load=HUGE), "load: integer too large"),
        (lambda r: r.scene(ZERO, load=math.inf), "load: must be finite, got inf"),
        (lambda r: r.inverse_solver(load=HUGE), "load: integer too large"),
        (lambda r: r.track([TARGET], load=HUGE), "load: integer too large"),
        (lambda r: r.inverse(TARGET, tol=HUGE), "tol: integer too large"),
        (lambda r: r.inverse(TARGET, max_iterations=HUGE), "max_iterations: integer too large"),
        (lambda r: r.inverse(TARGET, max_iterations=-1),
         "max_iterations: must be an integer in [1, 1000000], got -1"),
        (lambda r: r.inverse(TARGET, max_iterations=2.5), "max_iterations: must be an integer"),
        (lambda r: r.inverse(TARGET, max_iterations=True),
         "max_iterations: expected a number, got a boolean"),
        (lambda r: r.inverse(TARGET, strategy="fast"), "strategy: unknown strategy 'fast'"),
        (lambda r: r.track([TARGET], strategy=3), "strategy: expected a string, got a number"),
        (lambda r: r.inverse(TARGET, settings=3), "settings: expected an IkSettings or a dict"),
        (lambda r: r.inverse_solver().solve(TARGET, tol=0.0), "tol: must be positive"),
        (lambda r: r.inverse_solver().solve(TARGET, settings={"strategy": "geometric"}),
         "strategy: an InverseSolver finds the loaded equilibrium"),
        (
            lambda r: r.inverse_solver().solve(TARGET, max_iterations=HUGE),
            "max_iterations: integer too large",
        ),
        (lambda r: trajectories.circle(HUGE), "points: too large"),
        (lambda r: trajectories.circle(-3), "points: must not be negative, got -3"),
        (lambda r: trajectories.by_name(None), "name: expected a string, got NoneType"),
    ],
)
def test_bad_robot_arguments_name_the_argument(robot, call, message):
    with pytest.raises(ValueError, match="^" + re.escape(message)):
        call(robot)


def test_numpy_scalars_as_arguments(robot):
    a = robot.inverse(TARGET, load=np.float32(0.03), max_iterations=np.int64(60))
    b = robot.inverse(TARGET, load=0.03, max_iterations=60)
    assert a.reached and b.reached
    np.testing.assert_allclose(a.rest_curvature, b.rest_curvature, atol=1e-7)
    assert robot.inverse(TARGET, load=np.longdouble("0.03"), tol=np.array(1e-9)).reached


@pytest.mark.parametrize(
    "options,message",
    [
        ({"particles": HUGE}, "paper.particles: integer too large"),
        ({"seed": -1}, "paper.seed: must be a whole number in [0, 9007199254740992], got -1"),
        ({"chi": HUGE}, "paper.chi: integer too large"),
        ({"tol": None}, "paper.tol: expected a number, got null"),
        ({1: 2}, "paper: keys must be strings, got int"),
    ],
)
def test_paper_settings_name_the_field(options, message):
    with pytest.raises(ValueError, match="^" + re.escape(message)):
        softspine.solve(GOOD, method="paper", paper=options)


@pytest.mark.parametrize(
    "data,message",
    [
        ({**GOOD, 1: 2}, "scene: keys must be strings, got int"),
        (
            {**GOOD, "stiffness": {"kx": 1, ("ky",): 1}},
            "stiffness: keys must be strings, got tuple",
        ),
        (
            {**GOOD, "guides": [{"s": 0.5, None: 1}]},
            "guides[0]: keys must be strings, got NoneType",
        ),
    ],
)
def test_non_string_keys_name_the_path(data, message):
    with pytest.raises(ValueError, match="^" + re.escape(message)):
        Scene(data)


def test_non_string_robot_keys_name_the_robot():
    with pytest.raises(ValueError, match=r"^robot: keys must be strings, got float"):
        Robot({0.5: 1})


# --- Array arguments: the argument, the element and the expected shape -------------


def test_residual_blames_the_array_not_n_elements():
    scene = {**GOOD, "rest_curvature": [[1, 0], [0, 1], [1, 1]]}
    for rows in (8, 1, 0):
        q = np.zeros((rows, 4))
        q[:, 0] = 1
        expected = (
            r"^quaternions: expected shape \(n\+1, 4\) with n a positive multiple of the "
            rf"number of sections \(3\), got \({rows}, 4\)"
        )
        with pytest.raises(ValueError, match=expected):
            residual(scene, q)
    q = np.zeros((7, 4))
    q[:, 0] = 1
    assert residual(scene, q).shape == (6, 3)


def test_array_elements_are_named(robot):
    with pytest.raises(ValueError, match=r"^target: at \[1\]: must be finite, got NaN"):
        robot.inverse([0.1, math.nan, -0.9])
    with pytest.raises(ValueError, match=r"^target: expected 3 numbers, got 2"):
        robot.inverse(np.array([0.1, 0.2]))
    with pytest.raises(ValueError, match=r"^reference: at \[2\]\[0\]: must be finite, got inf"):
        k = np.zeros((10, 2))
        k[2, 0] = np.inf
        robot.inverse(TARGET, reference=k)
    with pytest.raises(ValueError, match=r"^rest_curvature: at \[0\]: expected 2 numbers, got 3"):
        robot.muscle_lengths(np.zeros((10, 3)))
    with pytest.raises(ValueError, match=r"^points: at \[0\]\[2\]: integer too large"):
        robot.track([[0.1, 0.0, HUGE]])


# --- JSON: duplicate keys, numbers out of range, exact numbers ---------------------


@pytest.mark.parametrize(
    "text,key",
    [
        ('{"length": 1, "length": 2, "stiffness": {"kx": 1, "ky": 1, "kz": 1}}', "length"),
        ('{"length": 1, "stiffness": {"kx": 1, "ky": 1, "kz": 1, "kx": 2}}', "stiffness.kx"),
        (
            '{"length": 1, "stiffness": {"kx": 1, "ky": 1, "kz": 1},'
            ' "guides": [{"s": 0.5, "position": [0, 0, 0.4], "s": 0.25}]}',
            r"guides\[0\]\.s",
        ),
    ],
)
def test_duplicate_json_keys_are_refused(text, key, tmp_path):
    with pytest.raises(ValueError, match=f"^{key}: invalid JSON: duplicate key at line 1"):
        Scene.from_json(text)
    path = tmp_path / "scene.json"
    path.write_text(text)
    with pytest.raises(ValueError, match=f"^{key}: invalid JSON: duplicate key"):
        softspine.solve(path)


def test_json_numbers_out_of_range_name_the_key():
    text = '{"length": 1, "stiffness": {"kx": 1, "ky": 1e400, "kz": 1}}'
    with pytest.raises(ValueError, match=r"^stiffness\.ky: invalid JSON: number out of range"):
        Scene.from_json(text)


def test_json_nesting_is_bounded_like_a_dict():
    text = '{"length": 1, "stiffness": {"kx": 1, "ky": 1, "kz": 1}, "tip_force": %s0%s}'
    with pytest.raises(ValueError, match=r"^tip_force(\[0\])+: invalid JSON: nested deeper"):
        Scene.from_json(text % ("[" * 40, "]" * 40))
    with pytest.raises(ValueError, match="invalid JSON"):
        Scene.from_json(text % ("[" * 30_000, "]" * 30_000))


def random_doubles(count: int, seed: int) -> list[float]:
    """Finite doubles spread over every exponent (random bit patterns)."""
    rng = random.Random(seed)
    out: list[float] = []
    while len(out) < count:
        x = struct.unpack("<d", rng.getrandbits(64).to_bytes(8, "little"))[0]
        if math.isfinite(x):
            out.append(x)
    return out


def test_json_numbers_read_back_exactly():
    xs = random_doubles(10_000, seed=11)
    scene = {**GOOD, "rest_curvature": [xs[i : i + 2] for i in range(0, len(xs), 2)]}
    back = Scene.from_json(json.dumps(scene)).to_dict()
    read = [x for row in back["rest_curvature"] for x in row]
    wrong = sum(a != b for a, b in zip(read, xs, strict=True))
    assert wrong == 0, f"{wrong} of {len(xs)} doubles changed"


def test_toml_errors_fit_on_one_line():
    with pytest.raises(ValueError) as info:
        Scene.from_toml("length = 1\nlength = 2\n")
    message = str(info.value)
    assert "\n" not in message and message.startswith("text: invalid TOML:"), message
    assert "line 2" in message


# --- Command line: one line on stderr and exit code 2 for a user error -------------


@pytest.mark.parametrize(
    "args,needle",
    [
        (["demo", "--scene", "no/such/scene.json"], "no/such/scene.json"),
        (["demo", "--scene", "."], "Is a directory"),
        (["demo", "--n-elements", "0"], "n_elements"),
        (["track", "--points", "-3"], "points: must not be negative, got -3"),
        (["track", "--points", "0"], "points: must be positive"),
        (["track", "--load", "-1"], "load"),
    ],
)
def test_cli_user_errors_are_one_line(args, needle, tmp_path):
    p = subprocess.run(
        [sys.executable, "-m", "softspine", *args, "--out", str(tmp_path / "x.png")],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert p.returncode == 2, p.stderr[-3000:]
    lines = p.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("softspine: error: "), p.stderr[-3000:]
    assert needle in lines[0]


def test_cli_bad_scene_file_is_one_line(tmp_path):
    bad = tmp_path / "bad.json"
    bad.write_text('{"length": 1, "length": -1, "stiffness": {"kx": 1, "ky": 1, "kz": 1}}')
    p = subprocess.run(
        [sys.executable, "-m", "softspine", "demo", "--scene", str(bad)],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert p.returncode == 2
    assert p.stderr.strip() == (
        "softspine: error: length: invalid JSON: duplicate key at line 1 column 22"
    )


# --- One InverseSolver shared between threads --------------------------------------


def test_inverse_solver_shared_between_threads():
    robot = Robot()
    targets = trajectories.circle(24)
    alone = robot.inverse_solver(0.03)
    expected = [alone.solve(p) for p in targets]
    shared = robot.inverse_solver(0.03)
    results: list = [None] * len(targets)
    errors: list[BaseException] = []

    def work(k: int) -> None:
        try:
            for i in range(k, len(targets), 4):
                results[i] = shared.solve(targets[i])
        except BaseException as e:  # noqa: BLE001 - reported below
            errors.append(e)

    threads = [threading.Thread(target=work, args=(k,)) for k in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert not errors, errors
    for got, want in zip(results, expected, strict=True):
        assert got.reached and want.reached
        np.testing.assert_allclose(got.rest_curvature, want.rest_curvature, atol=1e-4)
        np.testing.assert_allclose(got.tip_position, want.tip_position, atol=1e-8)


# --- One Solver shared between threads ---------------------------------------------


def test_a_solver_refuses_a_thread_between_another_threads_set_and_solve():
    # On 3e30b16 the second thread's set_* went through and the first thread
    # solved the second's actuation without a word (21 of 400 in a campaign).
    robot = Robot()
    mine, theirs = [[0.5, 0.2]] * robot.sections, [[-2.0, 1.0]] * robot.sections
    solver = softspine.Solver(robot.scene(mine, 0.03), n_elements=20)
    solver.set_rest_curvature(mine)
    outcome: list[str] = []

    def other_thread() -> None:
        for call in (lambda: solver.set_rest_curvature(theirs), solver.solve):
            try:
                call()
                outcome.append("accepted")
            except RuntimeError as e:
                outcome.append(str(e))

    t = threading.Thread(target=other_thread)
    t.start()
    t.join()
    assert len(outcome) == 2
    for message in outcome:
        assert message.startswith("Solver.") and "another thread changed" in message, message
    np.testing.assert_allclose(
        solver.solve().tip_position, robot.forward(mine, 0.03).tip_position, atol=1e-9
    )
    # Once solved, the solver serves whichever thread comes next.
    t = threading.Thread(target=lambda: solver.set_rest_curvature(theirs))
    t.start()
    t.join()
    solver.reset()
    solver.set_rest_curvature(mine)


def test_threads_sharing_a_solver_change_and_solve_in_one_call():
    robot = Robot()
    actuations = robot.workspace(16, 0.03, seed=3, progress=False).actuations
    expected = [robot.forward(k, 0.03).tip_position for k in actuations]
    solver = softspine.Solver(robot.scene(actuations[0], 0.03), n_elements=20)
    payload = solver.tip_force
    results: list = [None] * len(actuations)

    def work(k: int) -> None:
        for i in range(k, len(actuations), 4):
            results[i] = solver.solve(rest_curvature=actuations[i], tip_force=payload)

    threads = [threading.Thread(target=work, args=(k,)) for k in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    for got, want in zip(results, expected, strict=True):
        np.testing.assert_allclose(got.tip_position, want, atol=1e-9)


# --- Junk that was accepted ---------------------------------------------------------


@pytest.mark.parametrize(
    "junk", [memoryview(b"abc"), b"abc", bytearray(b"abc"), [1, memoryview(b"a"), 2]]
)
def test_bytes_are_not_numbers(junk):
    # memoryview(b"abc") became the tip force [97, 98, 99] on 3e30b16.
    with pytest.raises(ValueError, match="^tip_force"):
        Scene({**GOOD, "tip_force": junk})


@pytest.mark.parametrize("batch", ["forward_batch", "workspace", "inverse_batch"])
def test_part_without_an_executor_is_refused(batch):
    robot = Robot()
    first = {"forward_batch": np.zeros((2, robot.sections, 2)), "workspace": 2,
             "inverse_batch": [[0.05, 0.0, -0.9]]}[batch]
    with pytest.raises(ValueError, match="^part: "):
        getattr(robot, batch)(first, part={1, 2}, progress=False)
    with pytest.raises(ValueError, match="^part: "):
        softspine.solve_batch([GOOD], part=64, progress=False)


# --- solve()'s own arguments --

@pytest.mark.parametrize(
    "kwargs,message",
    [
        ({"n_elements": HUGE}, "n_elements: integer too large"),
        ({"max_iterations": HUGE}, "max_iterations: integer too large"),
        ({"tol": HUGE}, "tol: integer too large"),
        ({"residual_tol": HUGE}, "residual_tol: integer too large"),
        ({"method": 3}, "method: expected a string, got a number"),
        ({"method": "nope"}, "method: unknown method"),
        ({"refine": 3, "tol": 1e-3}, "refine: expected 'richardson' or None, got a number"),
    ],
)
def test_bad_solve_arguments_name_the_argument(kwargs, message):
    with pytest.raises(ValueError, match="^" + re.escape(message)):
        softspine.solve(GOOD, **kwargs)


# --- Every argument's refusal names it ----------------------------------------------

JUNK = [object(), None, True, -1, 2**64, math.nan, "abc", b"abc", memoryview(b"abc"),
        {1, 2}, [[1, 2]], 1 + 2j, np.zeros((2, 3)), np.full((1, 10, 2), np.nan)]
TENDON_ROBOT = "examples/robots/tendon_robot.toml"


def entry_points():
    """(entry point, the argument replaced, a call with that argument): every
    other argument valid. A refusal must name the argument."""
    robot = Robot()
    kappa = np.full((1, robot.sections, 2), 0.5)
    tips = robot.forward_batch(kappa, 0.01, progress=False).tip_positions
    solver = softspine.Solver(GOOD, n_elements=20)
    solver.solve()
    pool = ThreadPoolExecutor(1)
    calls = {
        "solve": ("scene settings n_elements method scheme initial tol residual_tol "
                  "max_iterations check",
                  lambda **k: softspine.solve(**{"scene": GOOD, **k})),
        "solve_batch": ("scenes settings shapes threads chunk",
                        lambda **k: softspine.solve_batch(**{"scenes": [GOOD], **k})),
        "calibrate": ("robot actuations measured_tips parameters load max_iterations threads",
                      lambda **k: softspine.calibrate(**{
                          "robot": robot, "actuations": kappa, "measured_tips": tips,
                          "parameters": ["stiffness.E"], "max_iterations": 1, **k})),
        "Robot.workspace": ("samples load seed first shapes threads chunk",
                            lambda **k: robot.workspace(**{"samples": 1, "progress": False,
                                                           **k})),
        "Robot.forward_batch": ("actuations load shapes warm_start threads chunk",
                                lambda **k: robot.forward_batch(**{"actuations": kappa,
                                                                   "progress": False, **k})),
        "Robot.inverse_batch": ("targets load reference direction settings threads chunk",
                                lambda **k: robot.inverse_batch(**{"targets": tips,
                                                                   "progress": False, **k})),
        "Robot.sensitivity": ("rest_curvature load parameters",
                              lambda **k: robot.sensitivity(**{"rest_curvature": kappa[0],
                                                               "parameters": "load", **k})),
        "Robot.muscle_lengths": ("rest_curvature",
                                 lambda **k: robot.muscle_lengths(**{"rest_curvature": kappa[0],
                                                                     **k})),
        "Robot.from_file": ("path", lambda **k: Robot.from_file(**{"path": TENDON_ROBOT, **k})),
        "Robot.from_json": ("text", lambda **k: Robot.from_json(**{"text": "{}", **k})),
        "Scene.from_toml": ("text", lambda **k: Scene.from_toml(**{"text": "length = 1", **k})),
        "Solver.solve": ("initial warm check rest_curvature tip_force tensions field",
                         lambda **k: solver.solve(**k)),
        "Solver.sensitivity": ("parameters",
                               lambda **k: solver.sensitivity(**{"parameters": "tip_force[0]",
                                                                 **k})),
        "trajectories.by_name": ("name points robot",
                                 lambda **k: trajectories.by_name(**{"name": "circle", **k})),
        "batch.concatenate": ("parts", lambda **k: softspine.batch.concatenate(**k)),
    }
    for name, (arguments, call) in calls.items():
        for argument in arguments.split():
            yield name, argument, call
    # On a cluster: every argument read before the batch is cut into parts.
    for argument in ("chunk", "part", "seed", "first"):
        yield "Robot.workspace(executor)", argument, lambda **k: robot.workspace(
            **{"samples": 1, "progress": False, "executor": pool, **k})
    for argument in ("actuations", "chunk", "part"):
        yield "Robot.forward_batch(executor)", argument, lambda **k: robot.forward_batch(
            **{"actuations": kappa, "progress": False, "executor": pool, **k})


@pytest.mark.parametrize("junk", JUNK, ids=lambda j: type(j).__name__)
def test_every_refusal_is_a_value_or_type_error_naming_the_argument(junk):
    # On 3e30b16: bare OverflowErrors (seed=-1), pyo3's "'int' object is not an
    # instance of 'bool'" (check=1), another argument blamed (calibrate's NaN
    # actuations as rest_curvature), int() and float() errors on a cluster.
    bad = []
    for name, argument, call in entry_points():
        try:
            call(**{argument: junk})
        except (ValueError, TypeError) as e:
            named = re.match(rf"^(\w+\.)?{argument}\b", str(e))
            if not named:
                bad.append(f"{name}({argument}={junk!r}): {type(e).__name__}: {e}")
        except Exception as e:  # noqa: BLE001 - every other type is the failure
            bad.append(f"{name}({argument}={junk!r}): {type(e).__name__}: {e}")
    assert not bad, "\n".join(bad)
