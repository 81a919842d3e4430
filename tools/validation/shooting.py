"""Shooting solution of the *continuous* Kirchhoff rod: an independent reference.

The rod is inextensible and unshearable. With arc length ``s`` in ``[0, L]``,
world position ``r``, unit quaternion ``q`` (scalar first, material to world,
tangent = local ``+z``), world internal force ``n`` and world internal moment
``m`` (exerted by the part beyond ``s`` on the part before it)::

    r' = R(q) e3
    q' = 1/2 q * (0, u),        u = omega0(s) + K^-1 R(q)^T m
    m' = -r' x n
    n' = -f

Base: ``r(0) = 0``, ``q(0) = Q0``. The rest curvature ``omega0`` is piecewise
constant over equal sections, so the integration is restarted at every
section boundary (DOP853, tight tolerances).

Free tip (:func:`solve`): ``n(L) = P`` and ``m(L) = M``. Dead loads make the
force explicit, ``n(s) = P + (L - s) f``, so ``n(0)`` is known and the
shooting unknowns are the three components of ``m(0)``. Other tips fit the
same machinery (:func:`_integrate` takes both ``m(0)`` and ``n(0)``): a pinned
tip would shoot on ``(m(0), n(0))`` against ``(r(L) - r_target, m(L) - M)``,
a clamped tip against ``(r(L) - r_target, orientation error of q(L))``.

Robustness: the root finder (MINPACK ``hybr``) is wrapped in an adaptive
continuation in a factor ``lam`` that multiplies all loads and the rest
curvature, starting from the straight, unloaded rod (``m(0) = 0``).
"""

from __future__ import annotations

import math

import numpy as np
from scipy.integrate import solve_ivp
from scipy.optimize import root

__all__ = ["solve"]

# Continuation step control: the largest rotation [rad] of any material frame
# (checked on _SHAPE_SAMPLES points) between two accepted load steps.
_MAX_FRAME_TURN = 0.5
_SHAPE_SAMPLES = 33


def _arr(scene: dict, key: str, default: list) -> np.ndarray:
    """Optional vector entry of a scene (``default`` when absent)."""
    value = scene.get(key)
    return np.asarray(default if value is None else value, dtype=float).reshape(len(default))


def _parse(scene: dict) -> dict:
    """Scene dict -> model data (deliberately independent of ``reference.normalize``).

    Keys: ``L``, ``K`` (3,), ``omega0_sections`` (m, 3), ``f``, ``P``, ``M`` (3,),
    ``Q0`` (4,, unit).
    """
    stiffness = scene["stiffness"]
    if "kx" in stiffness:
        K = np.array([stiffness["kx"], stiffness["ky"], stiffness["kz"]], dtype=float)
    else:
        d4 = float(stiffness["diameter"]) ** 4
        bend = float(stiffness["E"]) * math.pi * d4 / 64.0
        K = np.array([bend, bend, float(stiffness["G"]) * math.pi * d4 / 32.0])
    if np.any(K <= 0.0):
        raise ValueError("stiffnesses must be positive")
    kappa = scene.get("rest_curvature")
    kappa = np.zeros((1, 2)) if kappa is None else np.asarray(kappa, dtype=float).reshape(-1, 2)
    f = _arr(scene, "distributed_force", [0.0, 0.0, 0.0])
    if scene.get("gravity") is not None:
        grav = scene["gravity"]
        f = f + float(grav["linear_density"]) * np.asarray(grav["vector"], dtype=float)
    q0 = _arr(scene, "base_quaternion", [1.0, 0.0, 0.0, 0.0])
    if scene.get("tip", {"type": "free"}).get("type", "free") != "free":
        raise NotImplementedError("only a free tip is implemented")
    return {
        "L": float(scene["length"]),
        "K": K,
        "omega0_sections": np.column_stack([kappa, np.zeros(len(kappa))]),
        "f": f,
        "P": _arr(scene, "tip_force", [0.0, 0.0, 0.0]),
        "M": _arr(scene, "tip_moment", [0.0, 0.0, 0.0]),
        "Q0": q0 / np.linalg.norm(q0),
    }


def _rhs(s: float, y: np.ndarray, kinv: tuple, u0: tuple, f: tuple) -> list:
    """Right-hand side for the state ``y = [r (3), q (4), m (3), n (3)]``.

    Written with plain floats: it is called tens of thousands of times.
    """
    _, _, _, w, x, yq, z, mx, my, mz, nx, ny, nz = y
    inv = 1.0 / math.sqrt(w * w + x * x + yq * yq + z * z)
    qw, qx, qy, qz = w * inv, x * inv, yq * inv, z * inv  # R(q) of the unit quaternion
    r11 = 1.0 - 2.0 * (qy * qy + qz * qz)
    r12 = 2.0 * (qx * qy - qw * qz)
    r13 = 2.0 * (qx * qz + qw * qy)
    r21 = 2.0 * (qx * qy + qw * qz)
    r22 = 1.0 - 2.0 * (qx * qx + qz * qz)
    r23 = 2.0 * (qy * qz - qw * qx)
    r31 = 2.0 * (qx * qz - qw * qy)
    r32 = 2.0 * (qy * qz + qw * qx)
    r33 = 1.0 - 2.0 * (qx * qx + qy * qy)
    # body curvature u = omega0 + K^-1 R^T m
    ux = u0[0] + kinv[0] * (r11 * mx + r21 * my + r31 * mz)
    uy = u0[1] + kinv[1] * (r12 * mx + r22 * my + r32 * mz)
    uz = u0[2] + kinv[2] * (r13 * mx + r23 * my + r33 * mz)
    # q' = 1/2 q * (0, u) (with the unnormalised q: keeps |q| constant)
    dw = 0.5 * (-x * ux - yq * uy - z * uz)
    dx = 0.5 * (w * ux + yq * uz - z * uy)
    dy = 0.5 * (w * uy - x * uz + z * ux)
    dz = 0.5 * (w * uz + x * uy - yq * ux)
    # m' = -r' x n, r' = R e3
    dmx = -(r23 * nz - r33 * ny)
    dmy = -(r33 * nx - r13 * nz)
    dmz = -(r13 * ny - r23 * nx)
    return [r13, r23, r33, dw, dx, dy, dz, dmx, dmy, dmz, -f[0], -f[1], -f[2]]


def _integrate(
    model: dict,
    lam: float,
    m0: np.ndarray,
    n0: np.ndarray,
    rtol: float,
    s_eval: np.ndarray | None = None,
):
    """Integrate from the base to the tip, section by section.

    Loads and rest curvature are scaled by ``lam``; ``m0`` and ``n0`` are the
    world internal moment and force at the base. Returns the state at ``L``
    (13,) and, if ``s_eval`` is given, the states there (len(s_eval), 13).
    """
    length = model["L"]
    sections = lam * model["omega0_sections"]
    kinv = tuple(1.0 / model["K"])
    f = tuple(lam * model["f"])
    y = np.concatenate([np.zeros(3), model["Q0"], m0, n0])
    m = len(sections)
    bounds = np.linspace(0.0, length, m + 1)
    bounds[-1] = length
    samples = None
    if s_eval is not None:
        samples = np.empty((len(s_eval), 13))
        owner = np.clip(np.searchsorted(bounds, s_eval, side="right") - 1, 0, m - 1)
    # absolute tolerances per component, in the units of r, q, m and n
    moment = float(np.max(model["K"])) / length + float(np.max(np.abs(m0)))
    force = float(np.max(model["K"])) / length**2 + float(np.max(np.abs(n0)))
    atol = rtol * np.repeat([length, 1.0, moment, force], [3, 4, 3, 3])
    for k in range(m):
        sol = solve_ivp(
            _rhs,
            (bounds[k], bounds[k + 1]),
            y,
            method="DOP853",
            rtol=rtol,
            atol=atol,
            dense_output=samples is not None,
            args=(kinv, tuple(sections[k]), f),
        )
        if not sol.success:
            raise RuntimeError(f"integration failed in section {k}: {sol.message}")
        if samples is not None and np.any(owner == k):
            # DOP853's 7th-order dense output inside the section
            t_eval = np.clip(s_eval[owner == k], bounds[k], bounds[k + 1])
            samples[owner == k] = sol.sol(t_eval).T
        y = sol.y[:, -1].copy()  # the state at the section end
        y[3:7] /= np.linalg.norm(y[3:7])  # renormalise q at every restart
    if samples is not None:
        samples[:, 3:7] /= np.linalg.norm(samples[:, 3:7], axis=1, keepdims=True)
    return y, samples


def _free_tip_base_force(model: dict, lam: float) -> np.ndarray:
    """``n(0) = P + L f`` for a free tip with dead loads."""
    return lam * (model["P"] + model["L"] * model["f"])


def _shoot_free(model: dict, lam: float, x0: np.ndarray, rtol: float):
    """Solve ``m(L) = lam M`` for the scaled base moment ``x = m(0) L / max(K)``."""
    unit = float(np.max(model["K"]) / model["L"])
    n0 = _free_tip_base_force(model, lam)

    def mismatch(x: np.ndarray) -> np.ndarray:
        try:
            y, _ = _integrate(model, lam, x * unit, n0, rtol)
        except RuntimeError:
            return np.full(3, 1e6)
        return (y[7:10] - lam * model["M"]) / unit

    sol = root(mismatch, x0, method="hybr", options={"xtol": 1e-13})
    err = float(np.max(np.abs(mismatch(sol.x))))
    return sol.x, err


def _frames(model: dict, lam: float, x: np.ndarray, rtol: float) -> np.ndarray:
    """Quaternions on a coarse grid of the solution with scaled base moment x."""
    unit = float(np.max(model["K"]) / model["L"])
    grid = np.linspace(0.0, model["L"], _SHAPE_SAMPLES)
    _, samples = _integrate(model, lam, x * unit, _free_tip_base_force(model, lam), rtol, grid)
    return samples[:, 3:7]


def solve(scene: dict, rtol: float = 1e-12, n_samples: int = 101) -> dict:
    """Equilibrium of the continuous Kirchhoff rod with a free tip (dead loads).

    Returns a dict with ``s`` (n_samples,), ``positions`` (n_samples, 3),
    ``quaternions`` (n_samples, 4), ``tip_position`` (3,), ``tip_quaternion``
    (4,), ``base_moment`` (3,) = ``m(0)`` (world frame: the moment of all loads
    about the base, i.e. what the rod applies to the clamp), ``base_force``
    (3,) = ``n(0)``, ``tip_moment_error`` (N m, the shooting mismatch) and
    ``lambda_steps`` (accepted continuation steps).

    The continuation step is accepted only if the root finder converged and
    no material frame of the rod turned by more than ``_MAX_FRAME_TURN`` since
    the previous step: shooting problems have many roots (e.g. looped
    cantilevers at large loads) and this keeps to the branch that grows
    continuously from the straight rod.
    """
    model = _parse(scene)
    unit = float(np.max(model["K"]) / model["L"])
    accept = max(1e3 * rtol, 1e-10)  # mismatch accepted at intermediate steps
    x = np.zeros(3)
    frames = _frames(model, 0.0, x, rtol)
    x_prev, lam_prev = x.copy(), 0.0
    lam, dlam, steps = 0.0, 1.0, 0
    err = 0.0
    while lam < 1.0:
        lam_try = min(1.0, lam + dlam)
        guess = x
        if lam > 0.0:  # secant predictor
            guess = x + (lam_try - lam) / (lam - lam_prev) * (x - x_prev)
        x_new, err_new = _shoot_free(model, lam_try, guess, rtol)
        ok = err_new <= accept
        if ok:
            frames_new = _frames(model, lam_try, x_new, rtol)
            dots = np.clip(np.abs(np.sum(frames_new * frames, axis=1)), 0.0, 1.0)
            ok = float(np.max(2.0 * np.arccos(dots))) <= _MAX_FRAME_TURN
        if ok:
            x_prev, lam_prev = x, lam
            x, lam, err, frames = x_new, lam_try, err_new, frames_new
            steps += 1
            dlam = min(2.0 * dlam, 1.0)
        else:
            dlam *= 0.5
            if dlam < 1e-4:
                raise RuntimeError(f"shooting continuation failed at load factor {lam:.6g}")

    s = np.linspace(0.0, model["L"], n_samples)
    tip, samples = _integrate(model, 1.0, x * unit, _free_tip_base_force(model, 1.0), rtol, s)
    return {
        "s": s,
        "positions": samples[:, 0:3],
        "quaternions": samples[:, 3:7],
        "tip_position": tip[0:3].copy(),
        "tip_quaternion": tip[3:7].copy(),
        "base_moment": x * unit,
        "base_force": _free_tip_base_force(model, 1.0),
        "tip_moment_error": err * unit,
        "lambda_steps": steps,
    }
