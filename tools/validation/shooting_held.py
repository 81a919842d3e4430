"""Shooting solution of the continuous Kirchhoff rod with a held tip: pinned (a
ball joint at a point) or clamped (position and orientation). An independent
reference for the reactions of the discrete model.

Same equations as :mod:`softspine.shooting` (and its integrator); the unknowns
are the base moment and force ``m(0), n(0)`` (6) and the end conditions are

* pinned: ``r(L) = p`` and ``m(L) = M`` (an applied tip moment, usually 0);
* clamped: ``r(L) = p`` and ``R(q(L)) = R(Q_tip)``.

The reaction of the support on the rod is ``n(L) - P`` (pinned; ``P`` an applied
tip force) or ``n(L)`` and ``m(L)`` (clamped), world frame. Continuation in a
factor ``lam`` scales the loads and the rest curvature and moves the target from
the straight rod's tip (and its orientation from the base's, by slerp).
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import root

from . import shooting
from .reference import _conj, _qmul
from .shooting import _MAX_FRAME_TURN, _SHAPE_SAMPLES, _integrate, _parse

__all__ = ["solve"]






def _slerp(a, b, t):
    rel = _qmul(_conj(a), b)
    angle = 2.0 * np.arctan2(np.linalg.norm(rel[1:]), rel[0])
    axis = rel[1:] / np.linalg.norm(rel[1:]) if np.linalg.norm(rel[1:]) > 0 else np.zeros(3)
    half = 0.5 * angle * t
    return _qmul(a, np.concatenate([[np.cos(half)], np.sin(half) * axis]))


def solve(scene: dict, rtol: float = 1e-12, n_samples: int = 101) -> dict:
    """Equilibrium with a pinned or clamped tip; returns ``s``, ``positions``,
    ``quaternions``, ``tip_position``, ``tip_quaternion``, ``tip_reaction_force``
    and, clamped, ``tip_reaction_moment`` (world frame, on the rod)."""
    tip = scene["tip"]
    kind = tip["type"]
    if kind not in ("pinned", "clamped"):
        raise ValueError("tip.type: expected 'pinned' or 'clamped'")
    model = _parse({**scene, "tip": {"type": "free"}})
    length = model["L"]
    target = np.asarray(tip["position"], dtype=float)
    free = shooting.solve({**scene, "tip": {"type": "free"}}, rtol=rtol)
    free_tip, free_q = free["tip_position"], free["tip_quaternion"]
    q_tip = None
    if kind == "clamped":
        q_tip = np.asarray(tip["quaternion"], dtype=float)
        q_tip = q_tip / np.linalg.norm(q_tip)
        if q_tip @ free_q < 0:
            q_tip = -q_tip
    k_max = float(np.max(model["K"]))
    moment_unit, force_unit = k_max / length, k_max / length**2

    def mismatch(x, lam):
        m0, n0 = x[:3] * moment_unit, x[3:] * force_unit
        try:
            y, _ = _integrate(model, 1.0, m0, n0, rtol)
        except RuntimeError:
            return np.full(6, 1e6)
        p = (1 - lam) * free_tip + lam * target
        out = np.empty(6)
        out[:3] = (y[0:3] - p) / length
        if q_tip is None:
            out[3:] = (y[7:10] - model["M"]) / moment_unit
        else:
            q = y[3:7] / np.linalg.norm(y[3:7])
            goal = _slerp(free_q, q_tip, lam)
            err = _qmul(_conj(goal), q)
            out[3:] = 2.0 * np.sign(err[0] if err[0] != 0 else 1.0) * err[1:]
        return out

    def frames(x, lam):
        grid = np.linspace(0.0, length, _SHAPE_SAMPLES)
        _, samples = _integrate(model, 1.0, x[:3] * moment_unit, x[3:] * force_unit, rtol, grid)
        return samples[:, 3:7]

    x = np.concatenate([free["base_moment"] / moment_unit, free["base_force"] / force_unit])
    shape = frames(x, 0.0)
    x_prev, lam_prev, lam, dlam = x.copy(), 0.0, 0.0, 0.25
    while lam < 1.0:
        lam_try = min(1.0, lam + dlam)
        guess = x if lam == 0.0 else x + (lam_try - lam) / (lam - lam_prev) * (x - x_prev)
        sol = root(mismatch, guess, args=(lam_try,), method="hybr", options={"xtol": 1e-14})
        ok = float(np.max(np.abs(mismatch(sol.x, lam_try)))) <= max(1e3 * rtol, 1e-10)
        if ok:
            new_shape = frames(sol.x, lam_try)
            dots = np.clip(np.abs(np.sum(new_shape * shape, axis=1)), 0.0, 1.0)
            ok = float(np.max(2.0 * np.arccos(dots))) <= _MAX_FRAME_TURN
        if ok:
            x_prev, lam_prev, x, lam, shape = x, lam, sol.x, lam_try, new_shape
            dlam = min(2 * dlam, 1.0)
        else:
            dlam *= 0.5
            if dlam < 1e-5:
                raise RuntimeError(f"shooting continuation failed at load factor {lam:.6g}")
    s = np.linspace(0.0, length, n_samples)
    end, samples = _integrate(model, 1.0, x[:3] * moment_unit, x[3:] * force_unit, rtol, s)
    out = {
        "s": s,
        "positions": samples[:, 0:3],
        "quaternions": samples[:, 3:7],
        "tip_position": end[0:3].copy(),
        "tip_quaternion": end[3:7] / np.linalg.norm(end[3:7]),
        "tip_reaction_force": end[10:13] - (model["P"] if q_tip is None else 0.0),
    }
    if q_tip is not None:
        out["tip_reaction_moment"] = end[7:10].copy()
    return out
