"""Contact: a catheter fed through an introducer into a curved vessel, step
by step (each insertion warm-started from the one before), riding the
vessel's walls (needs matplotlib: pip install 'softspine[plot]').

The vessel is a lumen: a tube about a smooth centreline through a few
points, 5 mm in radius narrowing to 3.5 mm, bending by 90 degrees and then
out of its plane; the straight introducer sheath before it is the same
tube. The catheter (0.25 m, 1.5 mm, E = 0.5 GPa) is clamped in a handle on
the vessel's axis and passes through a port (the sheath's valve) at the
vessel's entry; the handle pushes it in 5 mm a step: its insertion, the
base moved along its tangent, the catheter's length unchanged.

Run: python examples/catheter.py [out.png]
"""

from __future__ import annotations

import sys

import matplotlib.pyplot as plt
import numpy as np

import softspine
from softspine.plotting import plot_contacts, plot_obstacles

# The vessel's centreline [m] (the sheath first) and its radius at each point.
centreline = np.array([[-0.26, 0.0, 0.0], [-0.02, 0.0, 0.0], [0.03, 0.0, 0.0],
                       [0.07, 0.012, 0.0], [0.095, 0.045, 0.0], [0.105, 0.09, 0.01],
                       [0.1, 0.13, 0.04], [0.09, 0.16, 0.08]])
radius = np.r_[0.005, np.linspace(0.005, 0.0035, len(centreline) - 1)]
vessel = {"shape": "lumen", "centreline": centreline.tolist(), "radius": radius.tolist()}
length = 0.25
port = [-0.015, 0.0, 0.0]
catheter = {
    "length": length,
    "stiffness": {"E": 0.5e9, "G": 0.5e9 / 2.8, "diameter": 0.0015},
    # The material z axis (the tangent) along +x, into the vessel.
    "base_quaternion": [np.sqrt(0.5), 0.0, np.sqrt(0.5), 0.0],
    "obstacles": [vessel],
    "ports": [{"position": port}],
}


def inserted(depth: float, initial: np.ndarray | None) -> softspine.Solution:
    """The catheter with its tip `depth` [m] along the axis at rest (the
    handle at depth - length), warm from `initial`."""
    scene = {**catheter, "base_position": [depth - length, 0.0, 0.0]}
    return softspine.solve(scene, n_elements=50, initial=initial)


# Drawn: the last insertion solved at or before each of these depths.
marks = [0.06, 0.12, 0.2]
shown: dict[float, softspine.Solution] = {}
q, last = None, 0.0
failures = []
depths = np.round(np.arange(0.04, 0.2001, 0.005), 4)
for depth in depths:
    sol = inserted(float(depth), q)
    if not (sol.converged and sol.stable) and q is not None:
        # Where a whole step's contact set is too far from the last one's,
        # four shorter steps from the last shape.
        shape = q
        for between in np.linspace(last, depth, 5)[1:]:
            sol = inserted(float(between), shape)
            if not (sol.converged and sol.stable):
                break
            shape = sol.quaternions
    if not (sol.converged and sol.stable):
        failures.append(float(depth))
        print(f"{1e3 * depth:5.0f} mm: {sol.message}")
        continue
    q, last = sol.quaternions, float(depth)
    contacts = sol.contacts
    print(f"{1e3 * depth:5.0f} mm: {len(contacts['force'])} contacts, "
          f"{contacts['force'].sum() * 1e3:6.2f} mN on the wall in all, "
          f"{1e3 * np.linalg.norm(sol.ports['force'][0]):5.2f} mN on the port, "
          f"{sol.iterations} Newton steps, {sol.solve_time * 1e3:.2f} ms")
    mark = next((m for m in marks if m >= float(depth) - 1e-9), None)
    if mark is not None:
        shown[mark] = sol
print(f"{len(failures)} insertions of {len(depths)} not solved: {failures}")

fig = plt.figure(figsize=(7, 6.4))
ax = fig.add_subplot(projection="3d")
# The vessel and the catheter in it, not the sheath behind.
plot_obstacles([{**vessel, "centreline": centreline[1:].tolist(), "radius": radius[1:].tolist()}],
               ax, alpha=0.15)
for sol, colour in zip(shown.values(), ["tab:green", "tab:orange", "tab:blue"], strict=False):
    inside = sol.positions[sol.positions[:, 0] >= centreline[1, 0]]
    ax.plot(*inside.T, color=colour, lw=2,
            label=f"{1e3 * (sol.positions[0, 0] + length):.0f} mm in")
    plot_contacts(sol, ax, scale=0.5, color=colour)
ax.scatter(*port, color="k", s=12, label="port")
ax.set_box_aspect(np.ptp(centreline[1:], axis=0) + 0.02)
ax.view_init(elev=35, azim=-120)
ax.legend(loc="upper left", fontsize=8)
ax.set_title("a catheter fed through a port into a curved vessel\n"
             "(the wall's and the port's forces as arrows)")
fig.tight_layout()
out = sys.argv[1] if len(sys.argv) > 1 else "catheter.png"
fig.savefig(out, dpi=110)
print(f"wrote {out}")
