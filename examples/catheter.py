"""Contact: a catheter advanced through a curved vessel, step by step (each
insertion warm-started from the one before), riding the vessel's walls
(needs matplotlib: pip install 'softspine[plot]').

The vessel is a lumen: a tube about a smooth centreline through a few
points, 5 mm in radius narrowing to 3.5 mm, bending by 90 degrees and then
out of its plane. The catheter (1.5 mm, E = 0.5 GPa) is clamped on the
vessel's axis at its entry and pushed in 5 mm a step.

Run: python examples/catheter.py [out.png]
"""

from __future__ import annotations

import sys

import matplotlib.pyplot as plt
import numpy as np

import softspine
from softspine.plotting import plot_backbone, plot_contacts, plot_obstacles

# The vessel's centreline [m] and its radius at each point.
centreline = np.array([[-0.02, 0.0, 0.0], [0.03, 0.0, 0.0], [0.07, 0.012, 0.0],
                       [0.095, 0.045, 0.0], [0.105, 0.09, 0.01], [0.1, 0.13, 0.04],
                       [0.09, 0.16, 0.08]])
radius = np.linspace(0.005, 0.0035, len(centreline))
vessel = {"shape": "lumen", "centreline": centreline.tolist(), "radius": radius.tolist()}
catheter = {
    "stiffness": {"E": 0.5e9, "G": 0.5e9 / 2.8, "diameter": 0.0015},
    # The material z axis (the tangent) along +x, into the vessel.
    "base_quaternion": [np.sqrt(0.5), 0.0, np.sqrt(0.5), 0.0],
    "obstacles": [vessel],
}



def product(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The Hamilton product of quaternions [w, x, y, z]."""
    w1, x1, y1, z1 = a
    w2, x2, y2, z2 = b
    return np.array([w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2, w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
                     w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2, w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2])


def extended(q: np.ndarray, nodes: int) -> np.ndarray:
    """`q` with nodes added at the tip, each turned from the one before as the
    tip's last element turned (the curve continued, not the tangent)."""
    turn = product(q[-2] * [1.0, -1.0, -1.0, -1.0], q[-1])
    out = list(q)
    while len(out) < nodes:
        out.append(product(out[-1], turn))
    return np.array(out)


# Drawn: the last insertion solved at or before each of these lengths.
marks = [0.06, 0.12, 0.2]
shown: dict[float, softspine.Solution] = {}
q = None
failures = []
for length in np.round(np.arange(0.04, 0.2001, 0.005), 4):
    n = int(round(length / 0.005))
    # The last shape, its tip bending on as it bent: the start of the next.
    start: np.ndarray | None = None if q is None else extended(q, n + 1)
    sol = softspine.solve({**catheter, "length": float(length)}, n_elements=n, initial=start)
    if not (sol.converged and sol.stable):
        # Warm starts carry the path; a cold start is the fallback.
        sol = softspine.solve({**catheter, "length": float(length)}, n_elements=n)
    if not (sol.converged and sol.stable):
        failures.append(float(length))
        print(f"{1e3 * length:5.0f} mm: {sol.message}")
        continue
    q = sol.quaternions
    contacts = sol.contacts
    print(f"{1e3 * length:5.0f} mm: {len(contacts['force'])} contacts, "
          f"{contacts['force'].sum() * 1e3:6.2f} mN on the wall in all, "
          f"{sol.iterations} Newton steps, {sol.solve_time * 1e3:.2f} ms")
    mark = next((m for m in marks if m >= float(length) - 1e-9), None)
    if mark is not None:
        shown[mark] = sol
# Not yet: at some insertions Newton's contact set cycles and the solve gives
# up (issue 28: insertion as a drive coordinate, a QP that cannot cycle).
print(f"{len(failures)} insertions of {len(np.arange(0.04, 0.2001, 0.005))} not solved: "
      f"{failures}")

fig = plt.figure(figsize=(7, 6.4))
ax = fig.add_subplot(projection="3d")
plot_obstacles([vessel], ax, alpha=0.15)
for sol, colour in zip(shown.values(), ["tab:green", "tab:orange", "tab:blue"], strict=False):
    plot_backbone(sol, ax, nodes=False, color=colour, lw=2,
                  label=f"{1e3 * sol.length:.0f} mm in")
    plot_contacts(sol, ax, scale=0.5, color=colour)
ax.set_box_aspect(np.ptp(centreline, axis=0) + 0.02)
ax.view_init(elev=35, azim=-120)
ax.legend(loc="upper left", fontsize=8)
ax.set_title("a catheter advanced through a curved vessel\n(contact forces as arrows)")
fig.tight_layout()
out = sys.argv[1] if len(sys.argv) > 1 else "catheter.png"
fig.savefig(out, dpi=110)
print(f"wrote {out}")
