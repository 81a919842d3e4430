"""An independent reference for contact: a heavy planar elastica lying on a
rigid frictionless table with one end lifted to a height h, by shooting with
the lift-off point as an unknown (SciPy, sharing nothing with the solver).

The lifted part runs from the lift-off point (arc length 0 there) to the
lifted end (arc length a, the lifted length). Planar, inextensible:
`x' = cos theta`, `y' = sin theta`, `theta' = m / EI`, and with the weight w
per length the internal force (of the distal part on the proximal one) has
`n_x' = 0`, `n_y' = w`, the moment `m' = n_x sin theta - n_y cos theta`.
Nothing pulls sideways (a frictionless table, an end lifted vertically), so
`n_x = 0`. At the lift-off point the rod leaves the straight part on the
table: `y = theta = m = 0`; the shear `n_y(0)` there is an unknown (the table's
concentrated reaction is its jump). At the end `y(a) = h` and either `m(a) = 0`
(lifted by a force alone) or `theta(a) = 0` (held horizontal); the lifting
force is `n_y(a)`. Unknowns `(a, n_y(0))`, found by `scipy.optimize.root`
from the small-deflection answer (`docs/model.md`, "Contact with obstacles").
"""

from __future__ import annotations

import numpy as np
from scipy.integrate import solve_ivp
from scipy.optimize import root


def lifted_rod(ei: float, w: float, lift: float, horizontal: bool = False,
               rtol: float = 1e-12) -> tuple[float, float]:
    """The lifted length `a` [m] and the lifting force [N] of a heavy rod
    (bending stiffness `ei` [N m^2], weight `w` [N/m]) with one end lifted
    to `lift` [m] off a table, the end free to turn (`horizontal=False`) or
    held horizontal."""
    factor, share = (72.0, 1.0 / 3.0) if horizontal else (24.0, 0.5)
    a0 = (factor * ei * lift / w) ** 0.25

    def shoot(unknowns: np.ndarray) -> np.ndarray:
        a, shear = unknowns
        a = abs(a)

        def rhs(s: float, z: np.ndarray) -> list[float]:
            _x, _y, theta, m = z
            n_y = shear + w * s
            return [np.cos(theta), np.sin(theta), m / ei, -n_y * np.cos(theta)]

        end = solve_ivp(rhs, (0.0, a), [0.0, 0.0, 0.0, 0.0], rtol=rtol, atol=1e-14 * a,
                        method="DOP853").y[:, -1]
        scale = w * a * a
        return np.array([end[1] / a - lift / a,
                         (end[2] if horizontal else end[3] / scale)])

    found = root(shoot, [a0, -share * w * a0], tol=1e-13)
    # Judged by the end's conditions (root may stop at its step tolerance
    # with them met to round-off).
    miss = np.abs(shoot(found.x)).max()
    if not miss < 1e-10:
        raise RuntimeError(f"lifted_rod: shooting missed the end by {miss:.1e}")
    a, shear = found.x
    return abs(a), shear + w * abs(a)


def knife_edge(ei: float, load: float, length: float, edge: float,
               rtol: float = 1e-12) -> tuple[float, float, float, float]:
    """A weightless cantilever, clamped at the origin along +x, with a
    downward force `load` [N] at its tip, resting on a frictionless knife
    edge at `(edge, 0)` [m] over which it may slide: the reaction's size [N],
    the arc length where it touches, and the tip's `(x, z)` [m].

    Planar (x, z up, the angle `theta` from +x), inextensible: `x' = cos
    theta`, `z' = sin theta`, `theta' = m / EI`, with `F(s)` the force of the
    distal part on the proximal one (the loads beyond s) and `m' = -(r' x F)`.
    The edge pushes along the rod's normal `(-sin theta_c, cos theta_c)` at
    the contact (frictionless). Unknowns: the base moment, the reaction, the
    contact's arc length and the rod's angle there; conditions: the rod
    passes through the edge at that arc length with that angle, no moment at
    the tip. Found by `scipy.optimize.root` from the small-deflection answer
    (the propped cantilever's `R = P (3 L - a) / (2 a)`)."""
    tip_force = np.array([0.0, -load])

    def cross(a: np.ndarray, b: np.ndarray) -> float:
        return float(a[0] * b[1] - a[1] * b[0])

    def integrate(z0: np.ndarray, s0: float, s1: float, force: np.ndarray) -> np.ndarray:
        if s1 <= s0:
            return z0

        def rhs(_s: float, z: np.ndarray) -> list[float]:
            _x, _z, theta, _m = z
            tangent = np.array([np.cos(theta), np.sin(theta)])
            return [tangent[0], tangent[1], z[3] / ei, -cross(tangent, force)]

        return solve_ivp(rhs, (s0, s1), z0, rtol=rtol, atol=1e-14 * length,
                         method="DOP853").y[:, -1]

    def shoot(unknowns: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        m0, reaction, s_c, theta_c = unknowns
        normal = np.array([-np.sin(theta_c), np.cos(theta_c)])
        before = integrate(np.array([0.0, 0.0, 0.0, m0]), 0.0, s_c,
                           tip_force + reaction * normal)
        after = integrate(before, s_c, length, tip_force)
        return before, after, normal

    def conditions(unknowns: np.ndarray) -> np.ndarray:
        before, after, _ = shoot(unknowns)
        return np.array([(before[0] - edge) / length, before[1] / length,
                         before[2] - unknowns[3], after[3] * length / ei])

    reaction0 = load * (3.0 * length - edge) / (2.0 * edge)
    m0 = -load * length + reaction0 * edge
    found = root(conditions, [m0, reaction0, edge, 0.0], tol=1e-14)
    miss = np.abs(conditions(found.x)).max()
    if not miss < 1e-10:
        raise RuntimeError(f"knife_edge: shooting missed by {miss:.1e}")
    _, after, _ = shoot(found.x)
    return float(found.x[1]), float(found.x[2]), float(after[0]), float(after[1])


def _planar(ei: float, force: tuple[float, float], start: np.ndarray, s0: float, s1: float,
            rtol: float = 1e-12):
    """A weightless planar elastica from `start = (x, y, theta, m)` at `s0`
    to `s1` under the constant internal force `force` (of the distal part
    on the proximal one): the dense solution of `solve_ivp`."""
    n_x, n_y = force

    def rhs(_s: float, z: np.ndarray) -> list[float]:
        _x, _y, theta, m = z
        return [np.cos(theta), np.sin(theta), m / ei, n_x * np.sin(theta) - n_y * np.cos(theta)]

    return solve_ivp(rhs, (s0, s1), start, rtol=rtol, atol=1e-15, method="DOP853",
                     dense_output=True)


def between_walls(ei: float, length: float, span: float, gap: float) -> dict:
    """A weightless elastica clamped at both ends, at `(0, 0)` and `(span, 0)`
    along +x, compressed (`span < length`) between the frictionless walls
    `y = gap` and `y = -gap`, buckled towards `+y`: the clamped-clamped case
    of Domokos, Holmes and Royce (1997), by shooting over half the rod (it
    is symmetric about its middle), in its first two regimes.

    Free until the first mode's middle reaches the upper wall; then a point
    contact at the middle, whose force `-2 n_y` is the jump of the shear
    there, while the middle's curvature bends away from the wall. Unknowns
    the internal force `(n_x, n_y)` and the clamp's moment; conditions at
    the middle: `x = span / 2`, `y = gap` and `theta = 0`. Past the point
    contact (the middle's moment reaching zero) the symmetric states are not
    covered: a `RuntimeError`. Returns `regime` ("free" or "point"),
    `contacts` (arc length, force), `compression` (`-n_x`) and `y(s)`, the
    deflection at arc lengths `s`."""
    half = 0.5 * length

    def end(force, m0):
        return _planar(ei, force, np.array([0.0, 0.0, 0.0, m0]), 0.0, half)

    def solved(equations, guess, name):
        found = root(equations, guess, tol=1e-14)
        miss = np.abs(equations(found.x)).max()
        if not miss < 1e-10:
            raise RuntimeError(f"between_walls ({name}): shooting missed by {miss:.1e}")
        return found.x

    def shape(sol):
        return lambda s: sol.sol(np.minimum(s, length - s))[1]

    # The free first mode whose middle reaches the wall: the first contact.
    def touching(u):
        e = end((u[0], 0.0), u[1]).y[:, -1]
        return [e[1] - gap, e[2]]

    first = solved(touching, [-4.0 * np.pi**2 * ei / length**2,
                              8.0 * np.pi**2 * ei * gap / length**2], "first contact")
    if span >= 2.0 * end((first[0], 0.0), first[1]).y[0, -1]:
        def free(u):
            e = end((u[0], 0.0), u[1]).y[:, -1]
            return [e[0] - 0.5 * span, e[2]]

        u = solved(free, first, "free")
        return {"regime": "free", "contacts": [], "compression": -u[0],
                "y": shape(end((u[0], 0.0), u[1]))}

    def point(u):
        e = end((u[0], u[1]), u[2]).y[:, -1]
        return [e[0] - 0.5 * span, e[1] - gap, e[2]]

    u = solved(point, [first[0], 0.0, first[1]], "point")
    sol = end((u[0], u[1]), u[2])
    if sol.y[3, -1] > 0.0:
        raise RuntimeError("between_walls: past the point contact (not covered)")
    return {"regime": "point", "contacts": [(half, -2.0 * u[1])], "compression": -u[0],
            "y": shape(sol)}


def rod_in_bend(ei: float, length: float, bend: float, clearance: float,
                inner: bool) -> dict:
    """A weightless rod clamped at the origin along +x, at the start of a
    rigid planar tube that bends towards +y about the centre `C = (0,
    bend)`; the backbone keeps within `clearance` of the tube's centreline
    (the tube's radius less the rod's). Pushed in to `length`, its tip rides
    the outer wall, `|r - C| = bend + clearance`, and, once long enough, a
    point of it the inner one, `|r - C| = bend - clearance`, tangentially.
    Frictionless: each force along the wall's normal, through `C`.

    Shooting from the clamp, the internal force constant between the
    contacts. Tip contact alone (`inner=False`): unknowns the clamp's moment
    and the tip force's size and angle; conditions the tip on the wall, the
    force through `C`, no moment at the tip. With the inner contact too: its
    arc length and force besides, conditions on the inner wall and tangent
    to it. Returns `contacts` (arc length, force, wall: "outer"/"inner") in
    order along the rod, `path(s)`, the backbone's (x, y) at `s`, and the
    shooting's `unknowns`."""
    centre = np.array([0.0, bend])
    outer, inner_radius = bend + clearance, bend - clearance

    def shoot(u):
        m0, f_tip, angle = u[:3]
        tip_force = f_tip * np.array([np.cos(angle), np.sin(angle)])
        if inner:
            s_1, f_1 = u[3], u[4]
            s_1 = np.clip(s_1, 1e-9, length)
            before = _planar(ei, tuple(tip_force), np.array([0.0, 0.0, 0.0, m0]), 0.0, s_1)
            at = before.y[:, -1]
            away = (at[:2] - centre) / np.linalg.norm(at[:2] - centre)
            # The distal part's loads: the tip force and, before s_1, the inner wall's.
            before = _planar(ei, tuple(tip_force + f_1 * away), np.array([0.0, 0.0, 0.0, m0]),
                             0.0, s_1)
            after = _planar(ei, tuple(tip_force), before.y[:, -1], s_1, length)
            return [before, after], tip_force
        return [_planar(ei, tuple(tip_force), np.array([0.0, 0.0, 0.0, m0]), 0.0, length)], \
            tip_force

    def conditions(u):
        parts, tip_force = shoot(u)
        tip = parts[-1].y[:, -1]
        to_centre = centre - tip[:2]
        out = [(np.linalg.norm(to_centre) - outer) / bend,
               float(to_centre[0] * tip_force[1] - to_centre[1] * tip_force[0])
               / max(abs(u[1]), 1e-300) / bend,
               tip[3] * bend / ei]
        if inner:
            at = parts[0].y[:, -1]
            radial = at[:2] - centre
            out += [(np.linalg.norm(radial) - inner_radius) / bend,
                    float(radial @ np.array([np.cos(at[2]), np.sin(at[2])])) / bend]
        return out

    if inner:
        # From the tip contact alone: the inner contact where that comes
        # nearest the inner wall, with a tenth of the tip's force.
        alone = rod_in_bend(ei, length, bend, clearance, inner=False)
        s = np.linspace(0.0, length, 401)
        nearest = s[np.argmin(np.linalg.norm(alone["path"](s) - centre, axis=1))]
        guess = [*alone["unknowns"], nearest, 0.1 * alone["unknowns"][1]]
    else:
        # Small deflection: a cantilever pushed up at its tip by the wall.
        rise = np.sqrt(length**2 + bend**2) - outer
        f0 = 3.0 * ei * max(rise, 1e-6) / length**3
        guess = [f0 * length, f0, np.arctan2(bend, -length)]
    found = root(conditions, guess, tol=1e-14)
    miss = np.abs(conditions(found.x)).max()
    if not miss < 1e-10:
        raise RuntimeError(f"rod_in_bend: shooting missed by {miss:.1e}")
    parts, _ = shoot(found.x)
    contacts = [(length, float(found.x[1]), "outer")]
    if inner:
        contacts.insert(0, (float(found.x[3]), float(found.x[4]), "inner"))

    def path(s):
        s = np.asarray(s, dtype=float)
        if not inner:
            return parts[0].sol(s)[:2].T
        s_1 = contacts[0][0]
        return np.where((s < s_1)[:, None], parts[0].sol(np.minimum(s, s_1))[:2].T,
                        parts[1].sol(np.maximum(s, s_1))[:2].T)

    return {"contacts": contacts, "path": path, "unknowns": found.x}


def through_port(ei: float, length: float, port: tuple[float, float], tip_load: float,
                 weight: float = 0.0, rtol: float = 1e-12, friction: float = 0.0,
                 slide: float = 1.0) -> dict:
    """A planar cantilever, clamped at the origin along +x, that passes
    through a port at `port = (a, h)` [m] and slides through it, with a
    downward force `tip_load` [N] at its tip and its weight `weight` [N/m]:
    the port's force `(f_x, f_z)` on the rod, the arc length that passes it,
    the angle there and the tip `(x, z)`. With `friction` (Coulomb's `mu`)
    the port also pushes the rod along itself by `mu |f|`, towards the tip
    for `slide = +1` (the rod sliding back through it) or the base for -1.

    Planar (x, z up, `theta` from +x), inextensible, as in `knife_edge`, with
    the internal force `F(s) = (0, -tip_load - weight (L - s))`, plus the
    port's force `f (-sin theta_c, cos theta_c)` proximal of it (across the
    rod: a frictionless port does no work as the rod slides, of either
    sign). Unknowns: the base moment, `f`, the arc length `s_c` and the angle
    `theta_c`; conditions: the rod passes through the port at `s_c` with the
    angle `theta_c`, no moment at the tip. Found by `scipy.optimize.root`
    along a load ramp from the weightless rod's answer."""
    a, h = port

    def integrate(z0, s0, s1, extra, scale):
        if s1 <= s0:
            return z0

        def rhs(s, z):
            theta = z[2]
            force = np.array([0.0, -scale * (tip_load + weight * (length - s))]) + extra
            return [np.cos(theta), np.sin(theta), z[3] / ei,
                    force[0] * np.sin(theta) - force[1] * np.cos(theta)]

        return solve_ivp(rhs, (s0, s1), z0, rtol=rtol, atol=1e-14 * length,
                         method="DOP853").y[:, -1]

    def shoot(u, scale):
        m0, f, s_c, theta_c = u
        normal = np.array([-np.sin(theta_c), np.cos(theta_c)])
        tangent = np.array([np.cos(theta_c), np.sin(theta_c)])
        force = f * normal + slide * friction * abs(f) * tangent
        before = integrate(np.array([0.0, 0.0, 0.0, m0]), 0.0, s_c, force, scale)
        after = integrate(before, s_c, length, np.zeros(2), scale)
        return before, after, force

    def conditions(u, scale):
        before, after, _ = shoot(u, scale)
        return np.array([(before[0] - a) / length, (before[1] - h) / length,
                         before[2] - u[3], after[3] * length / ei])

    # The unloaded rod through the port: a cantilever of length ~a bent by
    # an end force (small deflection: f = 3 EI h / a^3, slope 3 h / (2 a)).
    f0 = 3.0 * ei * h / a**3
    u = np.array([f0 * a, f0, np.hypot(a, h), 1.5 * h / a])
    for scale in (0.0, 0.25, 0.5, 0.75, 1.0):
        found = root(conditions, u, args=(scale,), tol=1e-14)
        u = found.x
    miss = np.abs(conditions(u, 1.0)).max()
    if not miss < 1e-10:
        raise RuntimeError(f"through_port: shooting missed by {miss:.1e}")
    _, after, force = shoot(u, 1.0)
    return {"force": force, "arc_length": float(u[2]), "angle": float(u[3]),
            "tip": (float(after[0]), float(after[1]))}


def stuck_in_port(ei: float, length: float, curvature: float, s_port: float,
                  tip_load: float, rtol: float = 1e-12) -> dict:
    """A planar rod of uniform rest curvature `curvature` [1/m] (curling up,
    `theta = curvature s` at rest), clamped at the origin along +x, whose
    material point `s_port` is held in a port at its rest place (a port with
    enough friction that the rod sticks in it), with a downward force
    `tip_load` [N] at its tip: the port's force `(f_x, f_z)` on the rod, the
    part of it along the rod there (its friction, towards the tip) and the
    part across, and the tip `(x, z)`, for each load scale in `scales`
    (`"ratios"`: `|along| / |across|` at each, the friction the path needs).

    The port holds the point, so its force is free in the plane: unknowns
    the base moment and that force, conditions the point at the port and no
    moment at the tip; `scipy.optimize.root` along the load ramp from the
    rest shape (zero force)."""
    port = np.array([np.sin(curvature * s_port), 1.0 - np.cos(curvature * s_port)]) / curvature

    def integrate(z0, s0, s1, extra, scale):
        def rhs(s, z):
            theta = z[2]
            force = np.array([0.0, -scale * tip_load]) + extra
            return [np.cos(theta), np.sin(theta), curvature + z[3] / ei,
                    force[0] * np.sin(theta) - force[1] * np.cos(theta)]

        return solve_ivp(rhs, (s0, s1), z0, rtol=rtol, atol=1e-14 * length,
                         method="DOP853").y[:, -1]

    def shoot(u, scale):
        m0, fx, fz = u
        before = integrate(np.array([0.0, 0.0, 0.0, m0]), 0.0, s_port, np.array([fx, fz]), scale)
        after = integrate(before, s_port, length, np.zeros(2), scale)
        return before, after

    def conditions(u, scale):
        before, after = shoot(u, scale)
        return np.array([(before[0] - port[0]) / length, (before[1] - port[1]) / length,
                         after[3] * length / ei])

    u = np.zeros(3)
    ratios = []
    for scale in np.linspace(0.1, 1.0, 10):
        u = root(conditions, u, args=(scale,), tol=1e-14).x
        theta = shoot(u, scale)[0][2]
        t = np.array([np.cos(theta), np.sin(theta)])
        along = u[1:] @ t
        ratios.append(abs(along) / np.linalg.norm(u[1:] - along * t))
    miss = np.abs(conditions(u, 1.0)).max()
    if not miss < 1e-10:
        raise RuntimeError(f"stuck_in_port: shooting missed by {miss:.1e}")
    before, after = shoot(u, 1.0)
    t = np.array([np.cos(before[2]), np.sin(before[2])])
    along = u[1:] @ t
    return {"force": u[1:].copy(), "along": float(along),
            "across": float(np.linalg.norm(u[1:] - along * t)), "ratios": ratios,
            "point": port, "tip": (float(after[0]), float(after[1]))}


def clamped_pinned(ei: float, length: float, span: float) -> dict:
    """A weightless planar elastica clamped at the origin along +x and pinned
    at `(span, 0)` (`span < length`: pushed along its own line, buckled
    towards `+y`), by shooting from the base with the unknowns `(m0, n_x,
    n_y)`: the base moment and the constant internal force (of the distal
    part on the proximal one), to `x(L) = span`, `y(L) = 0`, `m(L) = 0`.
    Followed from a span just short of the length (the column's first mode,
    `k L = 4.4934`, compression `20.19 EI / L^2`) in steps. Returns the pin's
    force on the rod `(n_x, n_y)` (the distal part of the rod's end is the
    pin), the base moment and `y(s)` (callable)."""
    k = 4.4934 / length

    def shoot(unknowns: np.ndarray):
        m0, n_x, n_y = unknowns
        return _planar(ei, (n_x, n_y), np.array([0.0, 0.0, 0.0, m0]), 0.0, length, rtol=1e-13)

    def conditions(unknowns: np.ndarray, target: float) -> np.ndarray:
        x, y, _theta, m = shoot(unknowns).y[:, -1]
        return np.array([(x - target) / length, y / length, m * length / ei])

    # The first mode, y = A (sin k s - k s cos k L ... ): start at a small
    # amplitude with the critical compression and a base moment of its sign.
    guess = np.array([0.05 * ei / length, -k * k * ei, 0.0])
    for target in np.linspace(length - 1e-4 * length, span, 12):
        found = root(conditions, guess, args=(target,), tol=1e-14)
        guess = found.x
    miss = np.abs(conditions(guess, span)).max()
    if not miss < 1e-10:
        raise RuntimeError(f"clamped_pinned: shooting missed by {miss:.1e}")
    solution = shoot(guess)
    return {"force": (float(guess[1]), float(guess[2])), "base_moment": float(guess[0]),
            "y": lambda s: solution.sol(s)[1]}
