"""An independent reference for point wrenches and distributed moments:
shooting on the continuous Kirchhoff rod, written with SciPy and sharing
nothing with the solver.

The rod: inextensible and unshearable, `r' = R e3`, `q' = q (0, u) / 2`,
`u = u0 + K^-1 R^T m`, internal force `n` and moment `m` (world frame, the
distal part on the proximal one) with `n' = -f` and `m' = -r' x n - l` (`l`
the dead moment per length). A point load `(F, M)` at `s_k` jumps them:
`n(s_k-) = n(s_k+) + F`, `m(s_k-) = m(s_k+) + M`. A free tip carries the tip
force and moment. The base moment is found by Newton (`scipy.optimize.root`)
after a load continuation from the rest shape.
"""

from __future__ import annotations

import numpy as np
from scipy.integrate import solve_ivp
from scipy.optimize import root


def _rotation(q):
    w, x, y, z = q / np.linalg.norm(q)
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
    ])


class WrenchRod:
    """A rod of equal sections (each its rest curvature, distributed force and
    moment), point loads at arc lengths, a free tip."""

    def __init__(self, scene):
        self.L = float(scene["length"])
        k = scene["stiffness"]
        self.K = np.array([k["kx"], k["ky"], k["kz"]], dtype=float)
        kappa = np.asarray(scene.get("rest_curvature", [[0.0, 0.0]]), dtype=float).reshape(-1, 2)
        own = scene.get("sections", [{}] * len(kappa))
        m = max(len(kappa), len(own))
        kappa = np.broadcast_to(kappa, (m, 2)) if len(kappa) == 1 else kappa
        self.bounds = np.linspace(0.0, self.L, m + 1)
        self.u0 = [np.array([a, b, 0.0]) for a, b in kappa]
        f = np.asarray(scene.get("distributed_force", [0.0, 0.0, 0.0]), dtype=float)
        if "gravity" in scene:
            g = scene["gravity"]
            f = f + g["linear_density"] * np.asarray(g["vector"], dtype=float)
        self.f = f
        rod_moment = np.asarray(scene.get("distributed_moment", [0.0, 0.0, 0.0]), dtype=float)
        self.l = [np.asarray(p.get("distributed_moment", rod_moment), dtype=float)
                  for p in (own if len(own) == m else [{}] * m)]
        self.points = [(float(p["s"]), np.asarray(p.get("force", [0, 0, 0]), dtype=float),
                        np.asarray(p.get("moment", [0, 0, 0]), dtype=float))
                       for p in scene.get("point_loads", [])]
        self.P = np.asarray(scene.get("tip_force", [0.0, 0.0, 0.0]), dtype=float)
        self.M = np.asarray(scene.get("tip_moment", [0.0, 0.0, 0.0]), dtype=float)
        self.Q0 = np.asarray(scene.get("base_quaternion", [1.0, 0.0, 0.0, 0.0]), dtype=float)

    def _rhs(self, s, y, u0, f, torque):
        q, m, n = y[3:7], y[7:10], y[10:13]
        R = _rotation(q)
        u = u0 + (R.T @ m) / self.K
        w, x, yy, z = q
        dq = 0.5 * np.array([
            -x * u[0] - yy * u[1] - z * u[2],
            w * u[0] + yy * u[2] - z * u[1],
            w * u[1] - x * u[2] + z * u[0],
            w * u[2] + x * u[1] - yy * u[0],
        ])
        t = R[:, 2]
        return np.concatenate([t, dq, -np.cross(t, n) - torque, -f])

    def shoot(self, lam, m0, samples=None, rtol=1e-12):
        """Integrate base to tip at load scale `lam` from the base moment `m0`:
        the tip state, and the states at `samples`."""
        stops = sorted(set(self.bounds[1:-1]) | {p[0] for p in self.points if p[0] < self.L})
        stops = [0.0, *stops, self.L]
        n0 = lam * (self.P + self.L * self.f + sum(F for _, F, _ in self.points))
        y = np.concatenate([np.zeros(3), self.Q0, m0, n0])
        out = {}
        for a, b in zip(stops[:-1], stops[1:], strict=True):
            sec = min(np.searchsorted(self.bounds, 0.5 * (a + b)) - 1, len(self.u0) - 1)
            sol = solve_ivp(self._rhs, (a, b), y, method="DOP853", rtol=rtol, atol=rtol * 1e-2,
                            dense_output=samples is not None,
                            args=(self.u0[sec], lam * self.f, lam * self.l[sec]))
            if samples is not None:
                for s in samples:
                    if a <= s <= b and s not in out:
                        out[s] = sol.sol(s)
            y = sol.y[:, -1].copy()
            y[3:7] /= np.linalg.norm(y[3:7])
            for s, F, M in self.points:
                if abs(s - b) < 1e-12 and b < self.L:
                    y[7:10] -= lam * M
                    y[10:13] -= lam * F
        return y, out

    def tip_moment(self, lam):
        at_tip = sum((M for s, _, M in self.points if abs(s - self.L) < 1e-12), np.zeros(3))
        return lam * (self.M + at_tip)

    def solve(self, samples, rtol=1e-12):
        """Positions and quaternions at `samples` (arc lengths)."""
        scale = self.K.max() / self.L
        m0 = np.zeros(3)
        for lam in np.linspace(0.0, 1.0, 11)[1:]:
            def mismatch(x, lam=lam):
                y, _ = self.shoot(lam, x * scale, rtol=rtol)
                return (y[7:10] - self.tip_moment(lam)) / scale
            sol = root(mismatch, m0 / scale, method="hybr", options={"xtol": 1e-14})
            assert np.abs(mismatch(sol.x)).max() < 1e-10, np.abs(mismatch(sol.x)).max()
            m0 = sol.x * scale
        _, states = self.shoot(1.0, m0, samples=list(samples), rtol=rtol)
        positions = np.array([states[s][:3] for s in samples])
        quats = np.array([states[s][3:7] / np.linalg.norm(states[s][3:7]) for s in samples])
        return positions, quats
