"""An independent reference for tendon-driven and magnetised rods: shooting
on the Cosserat rod equations with the Rucker-Webster tendon loads (Rucker
and Webster 2011) and the magnetic moment `(R m) x B` of a uniform field
(per length, and at the tip for a tip magnet), written with SciPy and sharing
nothing with the solver.

The rod: inextensible and unshearable, `p' = R e3`, `R' = R [u]x`, internal
force `n` and moment `m` (world frame), `m = R K (u - u0)` (the rod's own
moment), `n' = -f`, `m' = -p' x n - l`. A frictionless tendon under tension
`tau` at offset `rho(s)` runs along `p_i = p + R rho`; on the rod it exerts the
distributed force `f_i = tau (I - t t^T) p_i'' / |p_i'|` (`t` its unit tangent)
and moment `(R rho) x f_i`, and at its anchor the point force `-tau t` with
moment `(R rho) x (-tau t)`. Where the backbone's curvature jumps (a section
end, another tendon's anchor) a tendon running on is kinked and presses on the
rod with `tau (t+ - t-)` (the distributed law's `p_i''` holds a delta there).
`p_i''` holds `u'`, which `m'` holds in turn: the tendon loads are affine in
`u'`, and each step solves that 3x3 linear system. The base moment and force are found by
Newton (`scipy.optimize.root`) so that the tip carries the applied tip load.
"""

from __future__ import annotations

import numpy as np
from scipy.integrate import solve_ivp
from scipy.optimize import root


def skew(v):
    return np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])


def routing(tendon, s, starts=(0.0,), after=True):
    """Offset, its first and second derivatives (material frame). A tendon
    routed section by section (one offset a section, the sections starting at
    ``starts``) turns from its section's start; at a start, ``after`` picks
    the routing that begins there."""
    offsets = np.array(tendon["offset"], dtype=float).reshape(-1, 2)
    twists = np.broadcast_to(np.asarray(tendon.get("twist", 0.0), dtype=float), len(offsets))
    inside = [a for a in starts[1 : len(offsets)] if (a <= s if after else a < s)]
    k = len(inside)
    (x, y), w, s = offsets[k], twists[k], s - starts[k]
    c, si = np.cos(w * s), np.sin(w * s)
    rho = np.array([c * x - si * y, si * x + c * y, 0.0])
    d1 = w * np.array([-rho[1], rho[0], 0.0])
    d2 = -(w**2) * rho
    return rho, d1, d2


def solve_reference(scene, samples, rtol=1e-12):
    """Node positions at the arc lengths ``samples`` of the tendon scene
    (a dict as softspine reads it: diagonal stiffness, rest curvature per
    section, gravity, tip force and moment, tendons, per-section
    ``sections`` with their own length, diagonal stiffness or linear density;
    a free tip)."""
    own = scene.get("sections", [{}])
    lengths = [p["length"] for p in own if "length" in p]
    length = scene.get("length", sum(lengths))

    def splitter(count):
        """The index of the section holding ``s``, of ``count`` equal
        sections, or of the scene's sections when they have their lengths."""
        if lengths and count == len(lengths):
            ends = np.cumsum(lengths)[:-1]
            return lambda s: int(np.searchsorted(ends, s, side="right"))
        return lambda s: min(int(s / length * count), count - 1)

    def section_ends(count):
        if lengths and count == len(lengths):
            return set(np.cumsum(lengths)[:-1].tolist())
        return {length * i / count for i in range(1, count)}

    def diagonal(table):
        return np.array([table[c] for c in ("kx", "ky", "kz")], dtype=float)

    grav = scene.get("gravity")
    vector = np.array(grav["vector"], dtype=float) if grav else np.zeros(3)
    density = grav["linear_density"] if grav else 0.0
    stiffnesses = [diagonal(p.get("stiffness", scene["stiffness"])) for p in own]
    forces = [p.get("linear_density", density) * vector for p in own]

    own_section = splitter(len(own))

    def stiff(s):
        return stiffnesses[own_section(s)]

    def weight(s):
        return forces[own_section(s)]

    sections = scene.get("rest_curvature", [[0.0, 0.0]])
    tendons = scene.get("tendons", [])
    field = np.array(scene.get("magnetic_field", [0, 0, 0]), dtype=float)
    magnetization = np.array(scene.get("magnetization", [[0, 0, 0]]), dtype=float).reshape(-1, 3)
    tip_magnet = np.array(scene.get("tip_magnet", [0, 0, 0]), dtype=float)
    tip_force = np.array(scene.get("tip_force", [0, 0, 0]), dtype=float)
    tip_moment = np.array(scene.get("tip_moment", [0, 0, 0]), dtype=float)
    ends = sorted({t.get("end", length) for t in tendons})
    breaks = sorted(
        section_ends(len(sections))
        | section_ends(len(own))
        | section_ends(len(magnetization))
        | {e for e in ends if e < length}
    )
    magnet_section, rest_section = splitter(len(magnetization)), splitter(len(sections))
    count = max(len(sections), len(own))
    starts = [0.0, *sorted(section_ends(count))]

    def route(t, s, after=True):
        return routing(t, s, starts, after)

    def magnet(s):
        return magnetization[magnet_section(s)]

    def rest(s):
        i = rest_section(s)
        return np.array([sections[i][0], sections[i][1], 0.0])

    def active(s):
        return [t for t in tendons if t.get("end", length) > s]

    def derivative(s, y, u0, k, f_ext):
        r = y[3:12].reshape(3, 3)
        n, m = y[12:15], y[15:18]
        u = u0 + (r.T @ m) / k
        dp = r[:, 2]

        # The tendons' loads are affine in u': f_i = f0_i + F_i u'.
        f0 = np.zeros(3)
        l0 = np.zeros(3)
        f_lin = np.zeros((3, 3))
        l_lin = np.zeros((3, 3))
        for t in active(s):
            rho, d1, d2 = route(t, s)
            a = np.cross(u, rho) + d1 + np.array([0, 0, 1.0])
            dpi = r @ a
            norm = np.linalg.norm(dpi)
            tt = dpi / norm
            across = (np.eye(3) - np.outer(tt, tt)) * (t["tension"] / norm)
            ddpi0 = r @ (np.cross(u, a) + np.cross(u, d1) + d2)
            fi0 = across @ ddpi0
            fi_lin = across @ r @ (-skew(rho))  # d(u' x rho)/du' = -[rho]x
            arm = skew(r @ rho)
            f0 += fi0
            l0 += arm @ fi0
            f_lin += fi_lin
            l_lin += arm @ fi_lin
        # A magnetised rod in a uniform field: the distributed moment (R m) x B.
        l0 = l0 + np.cross(r @ magnet(s), field)
        # u' = K^-1 (-u x R^T m + R^T m'), m' = -p' x n - l0 - l_lin u'.
        mp0 = -np.cross(dp, n) - l0
        lhs = np.eye(3) + (r.T @ l_lin) / k[:, None]
        rhs = (-np.cross(u, r.T @ m) + r.T @ mp0) / k
        du = np.linalg.solve(lhs, rhs)
        mp = mp0 - l_lin @ du
        f_tendons = f0 + f_lin @ du
        dn = -f_ext - f_tendons
        dr = r @ skew(u)
        return np.concatenate([dp, dr.ravel(), dn, mp])

    def tangent(t, r, u, s, after=True):
        rho, d1, _ = route(t, s, after)
        dpi = r @ (np.cross(u, rho) + d1 + np.array([0, 0, 1.0]))
        return r @ rho, dpi / np.linalg.norm(dpi)

    def across(y, b, u0_before, u0_after, k_before, k_after):
        """The force and moment just past a break at ``b``: an anchor's point
        load (its tendon pulls back along its last direction), and, where the
        curvature jumps (a section end, an anchor), the kink force
        ``tau (t+ - t-)`` of every tendon that runs on, which depends on the
        curvature after the break: a fixed point (its contraction is about
        tau |rho|^2 / k)."""
        r = y[3:12].reshape(3, 3)
        n, m = y[12:15].copy(), y[15:18].copy()
        u_before = u0_before + (r.T @ m) / k_before
        for t in tendons:
            if abs(t.get("end", length) - b) < 1e-12:
                arm, unit = tangent(t, r, u_before, b, after=False)
                force = -t["tension"] * unit
                n -= force
                m -= np.cross(arm, force)
        running = [t for t in tendons if t.get("end", length) > b + 1e-12]
        n_after, m_after = n, m
        for _ in range(100):
            u_after = u0_after + (r.T @ m_after) / k_after
            n_next, m_next = n.copy(), m.copy()
            for t in running:
                arm, before = tangent(t, r, u_before, b, after=False)
                arm_after, after = tangent(t, r, u_after, b)
                # A change of routing: the tendon crosses the disk from its
                # old hole to its new one, bending at each.
                cross = arm_after - arm
                turns = [(arm, after, before)]
                if np.linalg.norm(cross) > 0:
                    d = cross / np.linalg.norm(cross)
                    turns = [(arm, d, before), (arm_after, after, d)]
                for at, out_dir, in_dir in turns:
                    force = t["tension"] * (out_dir - in_dir)
                    n_next -= force
                    m_next -= np.cross(at, force)
            done = np.abs(m_next - m_after).max() < 1e-15 * (1 + np.abs(m_next).max())
            n_after, m_after = n_next, m_next
            if done:
                break
        return np.concatenate([n_after, m_after])

    def shoot(unknowns, keep=None):
        y = np.concatenate([np.zeros(3), np.eye(3).ravel(), unknowns[:3], unknowns[3:]])
        points = [0.0, *breaks, length]
        out = {}
        for a, b in zip(points[:-1], points[1:], strict=True):
            mid = 0.5 * (a + b)
            u0, k, f_ext = rest(mid), stiff(mid), weight(mid)
            t_eval = None
            if keep is not None:
                t_eval = [x for x in keep if a <= x <= b]
            sol = solve_ivp(
                lambda s, y, u0=u0, k=k, f_ext=f_ext: derivative(s, y, u0, k, f_ext),
                (a, b),
                y,
                method="DOP853",
                rtol=rtol,
                atol=rtol * 0.1,
                t_eval=t_eval,
            )
            if keep is not None:
                for x, col in zip(sol.t, sol.y.T, strict=True):
                    out.setdefault(round(x, 12), col[:3])
            y = sol.y[:, -1].copy()
            if b < length:
                y[12:18] = across(y, b, u0, rest(b + 1e-9), k, stiff(b + 1e-9))

        # Tendons anchored at the tip load it too.
        r = y[3:12].reshape(3, 3)
        u = rest(length - 1e-9) + (r.T @ y[15:18]) / stiff(length - 1e-9)
        n_tip, m_tip = y[12:15].copy(), y[15:18].copy()
        for t in tendons:
            if abs(t.get("end", length) - length) < 1e-12:
                rho, d1, _ = route(t, length, after=False)
                dpi = r @ (np.cross(u, rho) + d1 + np.array([0, 0, 1.0]))
                force = -t["tension"] * dpi / np.linalg.norm(dpi)
                n_tip -= force
                m_tip -= np.cross(r @ rho, force)
        applied_moment = tip_moment + np.cross(r @ tip_magnet, field)
        return np.concatenate([n_tip - tip_force, m_tip - applied_moment]), out

    guess = np.zeros(6)
    found = root(lambda x: shoot(x)[0], guess, method="hybr", options={"xtol": 1e-14})
    assert np.abs(shoot(found.x)[0]).max() < 1e-10, found.message
    _, points = shoot(found.x, keep=list(samples))
    return np.array([points[round(x, 12)] for x in samples])
