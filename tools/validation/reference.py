"""NumPy reference implementation of the *discrete* quaternion rod model.

This module is a deliberately plain, slow and independent implementation of
the discrete model described in ``docs/model.md`` (quaternion finite differences,
free tip, dead loads). It exists to check the fast Rust core: it shares no
code with it and solves the equilibrium in a different way (raw 4-vector
unknowns, unit-norm equations, complex-step Jacobian, dense Newton).

Model (``n`` elements, nodes ``0..n``, ``ds = L/n``; quaternions scalar first,
rotating material to world; the material tangent is local ``+z``):

* ``q_0 = Q0`` is fixed (clamped base), ``q_1..q_n`` are free.
* Element ``i`` joins ``a = q_{i-1}`` and ``b = q_i``; its curvature is
  ``omega_i = (2/ds) vec(conj(a) * b)`` and its mean tangent is
  ``T_i = (T(a) + T(a, b) + T(b)) / 3`` with ``T(q)`` the third column of the
  rotation matrix written as a homogeneous quadratic form of ``q`` and
  ``T(a, b)`` its symmetric bilinear form.
* Positions ``r_0`` (``base_position``), ``r_i = r_{i-1} + ds T_i``.
* Internal force at node ``j``: ``F_j = P + (L - s_j) f``; ``Fbar_i`` is the
  mean of the element's two nodal forces.
* Potential ``Pi(q) = sum_i ds [1/2 e_i^T K e_i - Fbar_i . T_i]`` with
  ``e_i = omega_i - omega0_i``.
* Residual at node ``j``: ``1/2 G(q_j) dPi/dq_j`` (body-frame torque, with
  ``G(a) b = vec(conj(a) * b)``), minus ``R(q_n)^T M`` at the tip. This is
  ``d/dtheta Pi(q_j * exp(theta/2))`` at ``theta = 0``.

Every formula here is a polynomial in the quaternion components, so the
residual accepts complex arrays and its Jacobian is taken by complex step.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.linalg import solve_banded

__all__ = ["normalize", "energy", "positions", "forces", "residual", "solve"]

# ---------------------------------------------------------------------------
# Quaternion algebra (vectorised over leading axes, complex-safe: no abs/sqrt)
# ---------------------------------------------------------------------------

_CONJ = np.array([1.0, -1.0, -1.0, -1.0])


def _qmul(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Hamilton product ``p * q`` of scalar-first quaternions."""
    pw, px, py, pz = p[..., 0], p[..., 1], p[..., 2], p[..., 3]
    qw, qx, qy, qz = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    return np.stack(
        [
            pw * qw - px * qx - py * qy - pz * qz,
            pw * qx + px * qw + py * qz - pz * qy,
            pw * qy - px * qz + py * qw + pz * qx,
            pw * qz + px * qy - py * qx + pz * qw,
        ],
        axis=-1,
    )


def _conj(q: np.ndarray) -> np.ndarray:
    """Quaternion conjugate (not the complex conjugate)."""
    return q * _CONJ


def _pure(v: np.ndarray) -> np.ndarray:
    """The pure quaternion ``(0, v)``."""
    zero = np.zeros(v.shape[:-1] + (1,), dtype=v.dtype)
    return np.concatenate([zero, v], axis=-1)


def _tangent_bilinear(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Symmetric bilinear form ``T(a, b)`` of the tangent; ``T(q, q)`` is ``R(q) e_z``."""
    aw, ax, ay, az = a[..., 0], a[..., 1], a[..., 2], a[..., 3]
    bw, bx, by, bz = b[..., 0], b[..., 1], b[..., 2], b[..., 3]
    return np.stack(
        [
            ax * bz + az * bx + aw * by + ay * bw,
            ay * bz + az * by - aw * bx - ax * bw,
            aw * bw - ax * bx - ay * by + az * bz,
        ],
        axis=-1,
    )


def _tangent_form_grad(F: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Gradient with respect to ``a`` of ``F . T(a, b)`` (a 4-vector, linear in ``b``)."""
    fx, fy, fz = F[..., 0], F[..., 1], F[..., 2]
    bw, bx, by, bz = b[..., 0], b[..., 1], b[..., 2], b[..., 3]
    return np.stack(
        [
            fx * by - fy * bx + fz * bw,
            fx * bz - fy * bw - fz * bx,
            fx * bw + fy * bz - fz * by,
            fx * bx + fy * by + fz * bz,
        ],
        axis=-1,
    )


def _rotate_to_body(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """``R(q)^T v`` for a unit quaternion (as the quadratic ``vec(conj(q) (0,v) q)``)."""
    return _qmul(_qmul(_conj(q), _pure(v)), q)[..., 1:]


# ---------------------------------------------------------------------------
# Scene normalisation
# ---------------------------------------------------------------------------


def _vec(value, size: int, name: str) -> np.ndarray:
    arr = np.asarray(value, dtype=float)
    if arr.shape != (size,) or not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be {size} finite numbers, got {value!r}")
    return arr


def normalize(scene: dict) -> dict:
    """Reduce a scene dict to the model's data.

    Returns a dict with ``L`` (float), ``K`` (3,) = ``(kx, ky, kz)``,
    ``omega0_sections`` (m, 3) rest curvature per section (material frame,
    zero twist; one zero section if the scene has none), ``f`` (3,) the
    distributed force including gravity, ``P`` (3,) tip force, ``M`` (3,) tip
    moment and ``Q0`` (4,) the unit base quaternion.
    """
    if "length" not in scene or "stiffness" not in scene:
        raise ValueError("a scene needs 'length' and 'stiffness'")
    length = float(scene["length"])
    if not (math.isfinite(length) and length > 0.0):
        raise ValueError(f"length must be positive, got {scene['length']!r}")

    stiffness = scene["stiffness"]
    if all(k in stiffness for k in ("kx", "ky", "kz")):
        K = np.array([stiffness["kx"], stiffness["ky"], stiffness["kz"]], dtype=float)
    elif all(k in stiffness for k in ("E", "G", "diameter")):
        d = float(stiffness["diameter"])
        bend = float(stiffness["E"]) * math.pi * d**4 / 64.0
        twist = float(stiffness["G"]) * math.pi * d**4 / 32.0
        K = np.array([bend, bend, twist])
    else:
        raise ValueError("stiffness needs kx, ky, kz or E, G, diameter")
    if not np.all(np.isfinite(K)) or np.any(K <= 0.0):
        raise ValueError(f"stiffnesses must be positive, got {K}")

    if scene.get("rest_curvature") is not None:
        kappa = np.asarray(scene["rest_curvature"], dtype=float)
        if kappa.ndim != 2 or kappa.shape[1] != 2 or kappa.shape[0] < 1:
            raise ValueError("rest_curvature must be a list of [kappa_x, kappa_y] pairs")
        omega0 = np.column_stack([kappa, np.zeros(len(kappa))])
    else:
        omega0 = np.zeros((1, 3))

    f = np.zeros(3)
    if scene.get("distributed_force") is not None:
        f = f + _vec(scene["distributed_force"], 3, "distributed_force")
    if scene.get("gravity") is not None:
        grav = scene["gravity"]
        f = f + float(grav["linear_density"]) * _vec(grav["vector"], 3, "gravity.vector")

    P = _vec(scene.get("tip_force", [0.0, 0.0, 0.0]), 3, "tip_force")
    M = _vec(scene.get("tip_moment", [0.0, 0.0, 0.0]), 3, "tip_moment")
    Q0 = _vec(scene.get("base_quaternion", [1.0, 0.0, 0.0, 0.0]), 4, "base_quaternion")
    norm = np.linalg.norm(Q0)
    if norm < 1e-12:
        raise ValueError("base_quaternion must be non-zero")
    tip = scene.get("tip", {"type": "free"})
    if tip.get("type", "free") != "free":
        raise NotImplementedError("the reference model handles a free tip only")
    return {
        "L": length,
        "K": K,
        "omega0_sections": omega0,
        "f": f,
        "P": P,
        "M": M,
        "Q0": Q0 / norm,
    }


def _model(scene: dict) -> dict:
    """Accept either a raw scene or an already normalised one."""
    return scene if "Q0" in scene and "K" in scene else normalize(scene)


def _element_omega0(model: dict, n: int) -> np.ndarray:
    """Rest curvature of each element, (n, 3)."""
    sections = model["omega0_sections"]
    m = len(sections)
    if n < 1 or n % m != 0:
        raise ValueError(f"n_elements ({n}) must be a positive multiple of the sections ({m})")
    return sections[np.arange(n) * m // n]


def _scaled(model: dict, lam: float) -> dict:
    """The model with loads and rest curvature multiplied by ``lam``."""
    out = dict(model)
    for key in ("omega0_sections", "f", "P", "M"):
        out[key] = lam * model[key]
    return out


# ---------------------------------------------------------------------------
# The discrete model
# ---------------------------------------------------------------------------


def forces(scene: dict, n: int) -> np.ndarray:
    """Nodal internal forces ``F_j = P + (L - s_j) f``, (n+1, 3), world frame."""
    model = _model(scene)
    s = np.linspace(0.0, model["L"], n + 1)
    return model["P"][None, :] + (model["L"] - s)[:, None] * model["f"][None, :]


def _check_q(q: np.ndarray) -> int:
    if q.ndim != 2 or q.shape[1] != 4 or q.shape[0] < 2:
        raise ValueError(f"q must have shape (n+1, 4), got {q.shape}")
    return q.shape[0] - 1


def _element_tangents(q: np.ndarray) -> np.ndarray:
    a, b = q[:-1], q[1:]
    return (_tangent_bilinear(a, a) + _tangent_bilinear(a, b) + _tangent_bilinear(b, b)) / 3.0


def energy(scene: dict, q: np.ndarray) -> float:
    """Total potential ``Pi(q)`` (elastic energy minus the work of the forces).

    The tip moment has no potential in 3D (a dead moment is not conservative
    on SO(3)); it enters the residual only.
    """
    model = _model(scene)
    q = np.asarray(q)
    n = _check_q(q)
    ds = model["L"] / n
    a, b = q[:-1], q[1:]
    omega = (2.0 / ds) * _qmul(_conj(a), b)[:, 1:]
    e = omega - _element_omega0(model, n)
    F = forces(model, n)
    Fbar = 0.5 * (F[:-1] + F[1:])
    elastic = 0.5 * np.sum(e * e * model["K"][None, :])
    work = np.sum(Fbar * _element_tangents(q))
    return float(ds * (elastic - work))


def positions(scene: dict, q: np.ndarray) -> np.ndarray:
    """Node positions ``r_0`` (the scene's ``base_position``, default the
    origin), ``r_i = r_{i-1} + ds T_i``, (n+1, 3)."""
    model = _model(scene)
    q = np.asarray(q)
    n = _check_q(q)
    ds = model["L"] / n
    steps = ds * _element_tangents(q)
    base = _vec(scene.get("base_position", [0.0, 0.0, 0.0]), 3, "base_position")
    return base + np.vstack([np.zeros((1, 3), dtype=steps.dtype), np.cumsum(steps, axis=0)])


def _gradient(model: dict, q: np.ndarray) -> np.ndarray:
    """``dPi/dq_j`` for the free nodes j = 1..n, (n, 4); complex-safe."""
    n = q.shape[0] - 1
    ds = model["L"] / n
    a, b = q[:-1], q[1:]
    omega = (2.0 / ds) * _qmul(_conj(a), b)[:, 1:]
    Ke = model["K"][None, :] * (omega - _element_omega0(model, n))
    F = forces(model, n)
    Fbar = 0.5 * (F[:-1] + F[1:])
    # Elastic part: d omega/db = (2/ds) G(a), d omega/da = -(2/ds) G(b), G(a)^T v = a * (0, v).
    grad_b = 2.0 * _qmul(a, _pure(Ke))
    grad_a = -2.0 * _qmul(b, _pure(Ke))
    # Load part: -ds Fbar . (T(a,a) + T(a,b) + T(b,b)) / 3.
    grad_b = grad_b - ds / 3.0 * (_tangent_form_grad(Fbar, a) + 2.0 * _tangent_form_grad(Fbar, b))
    grad_a = grad_a - ds / 3.0 * (2.0 * _tangent_form_grad(Fbar, a) + _tangent_form_grad(Fbar, b))
    grad = grad_b.copy()  # node j is the end "b" of element j ...
    grad[:-1] += grad_a[1:]  # ... and the start "a" of element j+1
    return grad


def _residual(model: dict, q: np.ndarray) -> np.ndarray:
    """Body-frame torque residual, (n, 3); complex-safe."""
    grad = _gradient(model, q)
    res = 0.5 * _qmul(_conj(q[1:]), grad)[:, 1:]
    res[-1] -= _rotate_to_body(q[-1], model["M"])
    return res


def residual(scene: dict, q: np.ndarray) -> np.ndarray:
    """Equilibrium residual (3n,), node-major: rows ``3(j-1)..3j-1`` belong to node j.

    Row block j is ``1/2 G(q_j) dPi/dq_j`` (body-frame torque, N m), minus
    ``R(q_n)^T M`` for the tip node.
    """
    model = _model(scene)
    q = np.asarray(q)
    _check_q(q)
    return _residual(model, q).ravel()


# ---------------------------------------------------------------------------
# Solver: square 4n system (3 torque rows + |q_j|^2 - 1 per node), Newton
# ---------------------------------------------------------------------------


def _system(model: dict, qfree: np.ndarray, scale: float) -> np.ndarray:
    """The 4n equations, node-major [3 torque rows / scale, |q_j|^2 - 1]."""
    q = np.vstack([model["Q0"][None, :].astype(qfree.dtype), qfree])
    torque = _residual(model, q) / scale
    unit = np.sum(qfree * qfree, axis=1, keepdims=True) - 1.0
    return np.concatenate([torque, unit], axis=1).ravel()


def _jacobian(model: dict, qfree: np.ndarray, scale: float) -> np.ndarray:
    """Exact Jacobian of :func:`_system` by complex step with a 3-colouring.

    The equations of node j involve nodes j-1, j, j+1 only, so all nodes of
    one colour (index mod 3) can be perturbed together.
    """
    n = qfree.shape[0]
    h = 1e-30
    J = np.zeros((4 * n, 4 * n))
    rows = np.arange(n)
    offset = (np.arange(3)[:, None] - rows[None, :]) % 3  # (colour, row node)
    offset[offset == 2] = -1
    for colour in range(3):
        col_node = rows + offset[colour]
        valid = (col_node >= 0) & (col_node < n)
        r, c = rows[valid], col_node[valid]
        for k in range(4):
            qp = qfree.astype(complex)
            qp[colour::3, k] += 1j * h
            d = (_system(model, qp, scale).imag / h).reshape(n, 4)
            for i in range(4):
                J[4 * r + i, 4 * c + k] = d[r, i]
    return J


_BAND = 7  # half-bandwidth of the Jacobian: 4x4 blocks, nodes j-1..j+1


def _solve_banded(J: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """Solve with the banded (block-tridiagonal) Jacobian in O(n).

    A banded LU also avoids multi-threaded dense BLAS, which is slow on small
    matrices on a busy machine.
    """
    size = J.shape[0]
    ab = np.zeros((2 * _BAND + 1, size))
    for offset in range(-_BAND, _BAND + 1):
        diag = np.diagonal(J, offset)
        if offset >= 0:
            ab[_BAND - offset, offset:] = diag
        else:
            ab[_BAND - offset, : size + offset] = diag
    return solve_banded((_BAND, _BAND), ab, rhs)


def _newton(model: dict, qfree: np.ndarray, scale: float, tol: float, max_iter: int):
    """Damped Newton on the square 4n system; returns (converged, q, torque_inf)."""
    q = qfree.copy()
    F = _system(model, q, scale)
    for _ in range(max_iter):
        torque_inf = np.max(np.abs(F.reshape(-1, 4)[:, :3]))
        if torque_inf <= tol and np.max(np.abs(F.reshape(-1, 4)[:, 3])) <= 1e-14:
            return True, q, torque_inf
        J = _jacobian(model, q, scale)
        try:
            step = _solve_banded(J, -F).reshape(-1, 4)
        except np.linalg.LinAlgError:
            return False, q, torque_inf
        if not np.all(np.isfinite(step)):
            return False, q, torque_inf
        norm0 = np.linalg.norm(F)
        t = 1.0
        while t >= 1.0 / 256:
            trial = q + t * step
            trial /= np.linalg.norm(trial, axis=1, keepdims=True)
            F_trial = _system(model, trial, scale)
            if np.linalg.norm(F_trial) < (1.0 - 1e-4 * t) * norm0:
                break
            t *= 0.5
        else:
            # No decrease: either the roundoff floor is reached or Newton failed.
            return torque_inf <= max(tol, 1e-12), q, torque_inf
        q, F = trial, F_trial
    torque_inf = np.max(np.abs(F.reshape(-1, 4)[:, :3]))
    return torque_inf <= tol, q, torque_inf


# Largest accepted Newton corrector (max |q_j - predicted q_j|) per continuation step.
_MAX_CORRECTOR = 0.1


def solve(scene: dict, n_elements: int = 20, tol: float = 1e-13) -> dict:
    """Equilibrium of the discrete model with a free tip.

    Unknowns are the raw quaternions ``q_1..q_n``; equations are the 3n
    torque rows of :func:`residual` (divided by ``max(K)/L``) and
    ``|q_j|^2 - 1 = 0``. Damped Newton with an exact (complex-step) Jacobian
    and a banded solve, each step followed by renormalising the ``q_j``;
    started from the straight rod, with adaptive continuation in a factor
    ``lam`` multiplying all loads and the rest curvature (a step is retried
    smaller if Newton fails or its corrector exceeds ``_MAX_CORRECTOR``, to
    stay on the branch that grows from the straight rod). Converged when the
    scaled torque rows are below ``tol`` in max-norm (or below 1e-12 if
    Newton stalls at roundoff).

    Returns a dict with ``quaternions`` (n+1, 4), ``positions`` (n+1, 3),
    ``tip_position``, ``tip_quaternion``, ``energy``, ``residual_norm`` (the
    2-norm of the 3n torque rows, N m), ``residual_scale`` (``max(K)/L``)
    and ``lambda_steps`` (accepted continuation steps).
    """
    model = normalize(scene)
    n = int(n_elements)
    _element_omega0(model, n)  # validates n against the number of sections
    scale = float(np.max(model["K"]) / model["L"])
    q = np.tile(model["Q0"], (n, 1))
    q_prev, lam_prev = q.copy(), 0.0
    lam, dlam, steps = 0.0, 0.25, 0
    while lam < 1.0:
        lam_try = min(1.0, lam + dlam)
        if lam > 0.0:  # secant predictor from the last two accepted states
            guess = q + (lam_try - lam) / (lam - lam_prev) * (q - q_prev)
            guess /= np.linalg.norm(guess, axis=1, keepdims=True)
        else:
            guess = q
        final = lam_try == 1.0
        ok, q_new, _ = _newton(
            _scaled(model, lam_try), guess, scale, tol if final else 1e-9, 40 if final else 15
        )
        # A large corrector means Newton may have left the branch of
        # equilibria followed from the straight rod: take a smaller step.
        if ok and np.max(np.abs(q_new - guess)) <= _MAX_CORRECTOR:
            q_prev, lam_prev = q, lam
            q, lam = q_new, lam_try
            steps += 1
            dlam = min(2.0 * dlam, 0.5)
        else:
            dlam *= 0.5
            if dlam < 1e-5:
                raise RuntimeError(f"continuation failed at load factor {lam:.6g}")
    q_all = np.vstack([model["Q0"], q])
    r = positions(model, q_all)
    torque = residual(model, q_all)
    return {
        "quaternions": q_all,
        "positions": r,
        "tip_position": r[-1].copy(),
        "tip_quaternion": q_all[-1].copy(),
        "energy": energy(model, q_all),
        "residual_norm": float(np.linalg.norm(torque)),
        "residual_scale": scale,
        "lambda_steps": steps,
    }
