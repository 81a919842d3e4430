"""Self-tests of the two pure-Python references.

* ``validation.shooting`` (continuous Kirchhoff rod) against closed forms.
* ``validation.reference`` (the discrete quaternion model) against closed forms,
  with its second-order convergence, and against the shooting solution on a 3D
  scene.

The two modules (tools/validation) import neither softspine nor its compiled
extension.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from validation import reference, shooting

# ---------------------------------------------------------------------------
# Closed forms (independent of both modules: rotation matrices only)
# ---------------------------------------------------------------------------

# Bisshopp and Drucker (1945): tip deflection along the load / L,
# shortening / L, tip angle [rad], for alpha = P L^2 / EI.
BISSHOPP_DRUCKER = {
    1: (0.30172077, 0.05643324, 0.46135195),
    3: (0.60325344, 0.25442018, 0.98601695),
    10: (0.81060902, 0.55499560, 1.43028554),
}


def quat_to_matrix(q) -> np.ndarray:
    w, x, y, z = np.asarray(q, dtype=float) / np.linalg.norm(q)
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )


def rotation_angle(R1: np.ndarray, R2: np.ndarray) -> float:
    """Angle of the relative rotation R1^T R2 (atan2 form: accurate near zero)."""
    A = R1.T @ R2
    sin = np.linalg.norm([A[2, 1] - A[1, 2], A[0, 2] - A[2, 0], A[1, 0] - A[0, 1]]) / 2.0
    return float(math.atan2(sin, (np.trace(A) - 1.0) / 2.0))


def skew(u) -> np.ndarray:
    return np.array([[0.0, -u[2], u[1]], [u[2], 0.0, -u[0]], [-u[1], u[0], 0.0]])


def rodrigues(u, s: float) -> np.ndarray:
    """exp(s [u]x)."""
    u = np.asarray(u, dtype=float)
    k = np.linalg.norm(u)
    if k * s == 0.0:
        return np.eye(3)
    A = skew(u / k)
    return np.eye(3) + math.sin(k * s) * A + (1 - math.cos(k * s)) * A @ A


def arc_offset(u, s: float) -> np.ndarray:
    """Material-frame position after arc length s of a rod of constant
    curvature u (u perpendicular to e3) starting along e3."""
    u = np.asarray(u, dtype=float)
    k = np.linalg.norm(u)
    e3 = np.array([0.0, 0.0, 1.0])
    if k == 0.0:
        return s * e3
    return math.sin(k * s) / k * e3 + (1 - math.cos(k * s)) / k * np.cross(u / k, e3)


def arc_chain(length, kappas, q0, s_eval):
    """Closed form of a chain of circular arcs (equal sections, curvatures
    [kappa_x, kappa_y] in the material frame), base at the origin with
    orientation q0. Returns positions (len(s_eval), 3) and the rotation
    matrices (len(s_eval), 3, 3)."""
    m = len(kappas)
    h = length / m
    starts_r, starts_R = [np.zeros(3)], [quat_to_matrix(q0)]
    for kx, ky in kappas:
        u = (kx, ky, 0.0)
        starts_r.append(starts_r[-1] + starts_R[-1] @ arc_offset(u, h))
        starts_R.append(starts_R[-1] @ rodrigues(u, h))
    pos, rot = [], []
    for s in s_eval:
        k = min(int(s / h), m - 1)
        u = (*kappas[k], 0.0)
        sigma = s - k * h
        pos.append(starts_r[k] + starts_R[k] @ arc_offset(u, sigma))
        rot.append(starts_R[k] @ rodrigues(u, sigma))
    return np.array(pos), np.array(rot)


def tip_tangent(q) -> np.ndarray:
    return quat_to_matrix(q)[:, 2]


# ---------------------------------------------------------------------------
# Scenes
# ---------------------------------------------------------------------------

LENGTH, EI, GJ = 0.7, 2.3, 1.8


def cantilever(alpha: float) -> dict:
    return {
        "length": LENGTH,
        "stiffness": {"kx": EI, "ky": EI, "kz": GJ},
        "tip_force": [alpha * EI / LENGTH**2, 0.0, 0.0],
    }


def end_moment(turn: float) -> dict:
    """Moment about body x (identity base) bending by ``turn`` radians."""
    return {
        "length": LENGTH,
        "stiffness": {"kx": EI, "ky": 1.4 * EI, "kz": GJ},
        "tip_moment": [turn * EI / LENGTH, 0.0, 0.0],
    }


ARC_KAPPAS = [[2.0, 0.0], [-1.0, 3.0], [0.5, -2.0], [1.5, 1.0]]
ARC_Q0 = [math.cos(0.3), math.sin(0.3) * 0.6, 0.0, math.sin(0.3) * 0.8]


def arcs() -> dict:
    return {
        "length": LENGTH,
        "stiffness": {"E": 2.0e9, "G": 0.8e9, "diameter": 0.004},
        "rest_curvature": ARC_KAPPAS,
        "base_quaternion": ARC_Q0,
    }


def scene_3d() -> dict:
    axis = np.array([0.3, -0.5, 0.8]) / np.linalg.norm([0.3, -0.5, 0.8])
    half = 0.6
    return {
        "length": 0.4,
        "stiffness": {"kx": 0.02, "ky": 0.03, "kz": 0.015},
        "rest_curvature": [[3.0, -1.0], [-2.0, 2.5]],
        "gravity": {"linear_density": 0.05, "vector": [0.0, 0.0, -9.81]},
        "distributed_force": [0.02, 0.0, 0.0],
        "tip_force": [0.05, -0.03, 0.02],
        "tip_moment": [0.002, -0.001, 0.003],
        "base_quaternion": [math.cos(half), *(math.sin(half) * axis)],
        "name": "3d",
    }


# ---------------------------------------------------------------------------
# Shooting vs closed forms
# ---------------------------------------------------------------------------


@pytest.mark.parametrize("alpha", [1, 3, 10])
def test_shooting_bisshopp_drucker(alpha):
    scene = cantilever(alpha)
    out = shooting.solve(scene)
    tip = out["tip_position"]
    t = tip_tangent(out["tip_quaternion"])
    deflection, shortening, angle = BISSHOPP_DRUCKER[alpha]
    assert abs(tip[0] / LENGTH - deflection) < 1e-7
    assert abs((LENGTH - tip[2]) / LENGTH - shortening) < 1e-7
    assert abs(math.atan2(t[0], t[2]) - angle) < 1e-7
    assert abs(tip[1]) < 1e-12
    # m(0) is the moment of the tip load about the base
    np.testing.assert_allclose(out["base_moment"], np.cross(tip, scene["tip_force"]), atol=1e-10)
    assert np.allclose(out["positions"][-1], tip, atol=1e-12)


@pytest.mark.parametrize("turn", [1.0, 2 * math.pi])
def test_shooting_end_moment_is_an_arc(turn):
    out = shooting.solve(end_moment(turn))
    pos, rot = arc_chain(LENGTH, [[turn / LENGTH, 0.0]], [1, 0, 0, 0], out["s"])
    np.testing.assert_allclose(out["positions"], pos, atol=1e-10 * LENGTH)
    for q, R in zip(out["quaternions"], rot, strict=True):
        assert rotation_angle(quat_to_matrix(q), R) < 1e-9
    if turn == 2 * math.pi:
        assert np.linalg.norm(out["tip_position"]) < 1e-10 * LENGTH


def test_shooting_end_moment_rotated_base():
    """Moment about the body y axis of a rotated base: arc of curvature M/ky."""
    scene = end_moment(0.0)
    q0 = ARC_Q0
    kappa = 2.5
    scene["tip_moment"] = list(quat_to_matrix(q0) @ [0.0, kappa * scene["stiffness"]["ky"], 0.0])
    scene["base_quaternion"] = q0
    out = shooting.solve(scene)
    pos, rot = arc_chain(LENGTH, [[0.0, kappa]], q0, out["s"])
    np.testing.assert_allclose(out["positions"], pos, atol=1e-10 * LENGTH)
    assert rotation_angle(quat_to_matrix(out["tip_quaternion"]), rot[-1]) < 1e-9


def test_shooting_rest_curvature_arcs():
    out = shooting.solve(arcs(), n_samples=41)
    pos, rot = arc_chain(LENGTH, ARC_KAPPAS, ARC_Q0, out["s"])
    np.testing.assert_allclose(out["positions"], pos, atol=1e-10 * LENGTH)
    for q, R in zip(out["quaternions"], rot, strict=True):
        assert rotation_angle(quat_to_matrix(q), R) < 1e-9
    np.testing.assert_allclose(out["base_moment"], 0.0, atol=1e-12)


# ---------------------------------------------------------------------------
# The discrete model: definitions
# ---------------------------------------------------------------------------


def _qmul(p, q):
    pw, pv = p[0], np.asarray(p[1:])
    qw, qv = q[0], np.asarray(q[1:])
    return np.concatenate([[pw * qw - pv @ qv], pw * qv + qw * pv + np.cross(pv, qv)])


def _expmap(theta):
    angle = np.linalg.norm(theta)
    if angle == 0.0:
        return np.array([1.0, 0.0, 0.0, 0.0])
    return np.concatenate([[math.cos(angle / 2)], math.sin(angle / 2) * theta / angle])


def _random_rod(scene: dict, n: int, seed: int) -> np.ndarray:
    """Unit quaternions of a randomly bent rod (node 0 = base)."""
    rng = np.random.default_rng(seed)
    q = [np.asarray(reference.normalize(scene)["Q0"])]
    for _ in range(n):
        q.append(_qmul(q[-1], _expmap(rng.normal(scale=0.3, size=3))))
    return np.array(q)


def test_normalize_and_forces():
    model = reference.normalize(arcs())
    bend = 2.0e9 * math.pi * 0.004**4 / 64
    np.testing.assert_allclose(model["K"], [bend, bend, 0.8e9 * math.pi * 0.004**4 / 32])
    assert model["omega0_sections"].shape == (4, 3)
    model = reference.normalize(scene_3d())
    np.testing.assert_allclose(model["f"], [0.02, 0.0, -0.05 * 9.81])
    F = reference.forces(scene_3d(), 8)
    s = np.linspace(0.0, 0.4, 9)
    np.testing.assert_allclose(F, model["P"] + (0.4 - s)[:, None] * model["f"])
    with pytest.raises(ValueError):
        reference.solve(arcs(), n_elements=10)  # 4 sections do not divide 10
    # the shooting module parses scenes on its own: it must agree
    for scene in (arcs(), scene_3d(), cantilever(3)):
        ref, sh = reference.normalize(scene), shooting._parse(scene)
        for key in ("L", "K", "omega0_sections", "f", "P", "M", "Q0"):
            np.testing.assert_allclose(sh[key], ref[key], rtol=1e-15, err_msg=key)


def test_residual_is_the_derivative_of_the_energy():
    """Residual rows = d/dtheta Pi(q_j exp(theta/2)), plus -R^T M at the tip."""
    scene = scene_3d()
    n = 6
    q = _random_rod(scene, n, seed=1)
    res = reference.residual(scene, q).reshape(n, 3)
    M = np.asarray(scene["tip_moment"])
    h = 1e-6
    for j in range(1, n + 1):
        for k in range(3):
            theta = np.zeros(3)
            theta[k] = h
            qp, qm = q.copy(), q.copy()
            qp[j] = _qmul(q[j], _expmap(theta))
            qm[j] = _qmul(q[j], _expmap(-theta))
            derivative = (reference.energy(scene, qp) - reference.energy(scene, qm)) / (2 * h)
            if j == n:
                derivative -= (quat_to_matrix(q[n]).T @ M)[k]
            assert abs(res[j - 1, k] - derivative) < 1e-7
    # positions are the sum of the mean tangents
    r = reference.positions(scene, q)
    assert r.shape == (n + 1, 3) and np.all(r[0] == 0.0)
    straight = np.tile(q[0], (n + 1, 1))
    np.testing.assert_allclose(reference.positions(scene, straight)[-1], 0.4 * tip_tangent(q[0]))


# ---------------------------------------------------------------------------
# The discrete model vs closed forms: second order
# ---------------------------------------------------------------------------


def _bd_error(alpha, out):
    tip = out["tip_position"] / LENGTH
    deflection, shortening, _ = BISSHOPP_DRUCKER[alpha]
    return math.hypot(tip[0] - deflection, 1.0 - tip[2] - shortening)


CLOSED_FORM_CASES = {
    "cantilever-1": (cantilever(1), lambda out: _bd_error(1, out)),
    "cantilever-3": (cantilever(3), lambda out: _bd_error(3, out)),
    "cantilever-10": (cantilever(10), lambda out: _bd_error(10, out)),
    "roll-up": (end_moment(2 * math.pi), lambda out: np.linalg.norm(out["tip_position"]) / LENGTH),
    "arcs": (
        arcs(),
        lambda out: (
            np.linalg.norm(
                out["tip_position"] - arc_chain(LENGTH, ARC_KAPPAS, ARC_Q0, [LENGTH])[0][0]
            )
            / LENGTH
        ),
    ),
}


def _check_solution(out, n):
    q = out["quaternions"]
    assert q.shape == (n + 1, 4)
    np.testing.assert_allclose(np.linalg.norm(q, axis=1), 1.0, atol=1e-14)
    assert out["residual_norm"] < 1e-12 * out["residual_scale"]
    np.testing.assert_array_equal(out["tip_position"], out["positions"][-1])


@pytest.mark.parametrize("case", sorted(CLOSED_FORM_CASES))
def test_reference_second_order_against_closed_forms(case):
    scene, error = CLOSED_FORM_CASES[case]
    errors = []
    for n in (20, 40, 80):
        out = reference.solve(scene, n_elements=n)
        _check_solution(out, n)
        errors.append(error(out))
    orders = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
    assert np.all((orders > 1.9) & (orders < 2.1)), (errors, orders)
    assert errors[0] < 2e-2


def test_reference_roll_up_discrete_closed_form():
    """Pure moment about body x: every element turns about x by the same angle.

    The element energy ds/2 K |omega|^2 with |omega| = 2 sin(theta/2)/ds has
    d/dtheta = K sin(theta)/ds, so the discrete equilibrium is
    sin(theta) = M ds / K (not |omega| = M/K, nor theta = M ds/K).
    """
    n = 20
    out = reference.solve(end_moment(2 * math.pi), n_elements=n)
    q = out["quaternions"]
    ds = LENGTH / n
    theta = math.asin(2 * math.pi / LENGTH * ds)
    step = [math.cos(theta / 2), math.sin(theta / 2), 0.0, 0.0]
    for i in range(1, n + 1):
        np.testing.assert_allclose(_qmul(q[i - 1] * [1, -1, -1, -1], q[i]), step, atol=1e-12)
    expected = [math.cos(n * theta / 2), math.sin(n * theta / 2), 0.0, 0.0]
    np.testing.assert_allclose(out["tip_quaternion"], expected, atol=1e-12)


def test_reference_matches_shooting_in_3d():
    scene = scene_3d()
    exact = shooting.solve(scene)
    tip_exact = exact["tip_position"]
    R_exact = quat_to_matrix(exact["tip_quaternion"])
    straight_tip = scene["length"] * tip_tangent(scene["base_quaternion"])
    assert np.linalg.norm(tip_exact - straight_tip) > 0.25 * scene["length"]  # really deformed
    tips, errors, angles = [], [], []
    for n in (40, 80):
        out = reference.solve(scene, n_elements=n)
        _check_solution(out, n)
        tips.append(out["tip_position"])
        errors.append(np.linalg.norm(out["tip_position"] - tip_exact) / scene["length"])
        angles.append(rotation_angle(quat_to_matrix(out["tip_quaternion"]), R_exact))
    assert 1.8 < math.log2(errors[0] / errors[1]) < 2.2, errors
    assert 1.8 < math.log2(angles[0] / angles[1]) < 2.2, angles
    richardson = (4 * tips[1] - tips[0]) / 3
    assert np.linalg.norm(richardson - tip_exact) / scene["length"] < errors[1] / 20
