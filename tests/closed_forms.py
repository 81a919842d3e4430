"""Closed-form references: Bisshopp-Drucker cantilever values, circular arcs and
chains of arcs (piecewise constant curvature without load)."""

from __future__ import annotations

import numpy as np

# alpha = P L^2 / EI: tip deflection along the load / L, shortening / L, tip angle.
BISSHOPP_DRUCKER = {
    1.0: (0.30172077, 0.05643324, 0.46135195),
    3.0: (0.60325344, 0.25442018, 0.98601695),
    10.0: (0.81060902, 0.55499560, 1.43028554),
}


def skew(v):
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def rotation_exp(u, s):
    """exp(s [u]x) (Rodrigues)."""
    k = np.linalg.norm(u)
    if k * s < 1e-14:
        return np.eye(3) + s * skew(u)
    a = skew(u / k)
    t = k * s
    return np.eye(3) + np.sin(t) * a + (1.0 - np.cos(t)) * a @ a


def arc_chain_tip(rest_curvature, length, base_rotation=None):
    """Tip position and rotation of a chain of equal arcs with body curvature
    [kx, ky, 0] each (an unloaded rod with piecewise constant rest curvature)."""
    m = len(rest_curvature)
    ell = length / m
    r = np.zeros(3)
    R = np.eye(3) if base_rotation is None else np.array(base_rotation, dtype=float)
    e3 = np.array([0.0, 0.0, 1.0])
    for kx, ky in rest_curvature:
        u = np.array([kx, ky, 0.0])
        k = np.linalg.norm(u)
        U = skew(u)
        if k < 1e-14:
            integral = ell * np.eye(3)
        else:
            integral = (
                ell * np.eye(3)
                + (1.0 - np.cos(k * ell)) / k**2 * U
                + (k * ell - np.sin(k * ell)) / k**3 * U @ U
            )
        r = r + R @ integral @ e3
        R = R @ rotation_exp(u, ell)
    return r, R


def quat_mul(a, b):
    """Hamilton product of scalar-first quaternions."""
    w1, x1, y1, z1 = a
    w2, x2, y2, z2 = b
    return np.array([
        w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2,
        w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
        w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
        w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2,
    ])


def quat_to_matrix(q):
    w, x, y, z = q
    return np.array(
        [
            [w * w + x * x - y * y - z * z, 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), w * w - x * x + y * y - z * z, 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), w * w - x * x - y * y + z * z],
        ]
    )


def observed_orders(errors):
    """log2 of successive error ratios (n doubling)."""
    e = np.asarray(errors, dtype=float)
    return np.log2(e[:-1] / e[1:])
