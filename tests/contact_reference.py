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
