"""Contact: a 3-section robot with 30 g at its tip reaching a target around
a ball that stands in the way of its free answer, and a heavy rod lifted off
a table (needs matplotlib: pip install 'softspine[plot]').

Run: python examples/contact.py [out.png]
"""

from __future__ import annotations

import sys

import matplotlib.pyplot as plt
import numpy as np

import softspine
from softspine.plotting import plot_backbone, plot_contacts, plot_obstacles

# The robot: the seed's, in 3 sections. Its free answer for the target...
target = [0.3, 0.0, -0.8]
free = softspine.Robot({"sections": 3}).inverse(target, load=0.03)
# ... passes where a ball now stands (its surface 2 cm into the robot's).
ball = {"shape": "sphere", "centre": (free.solution.positions[10] + [0.04, 0.0, 0.0]).tolist(),
        "radius": 0.05}
robot = softspine.Robot({"sections": 3, "obstacles": [ball]})
ik = robot.inverse(target, load=0.03)
contacts = ik.solution.contacts
print(f"robot: {ik.message}; tip miss {ik.tip_miss:.1e} m, {ik.iterations} iterations, "
      f"{ik.time * 1e3:.1f} ms; leaning on the ball at s = {contacts['arc_length']} m "
      f"with {contacts['force']} N")

# The heavy rod (EI = 1 N m^2, 1 N/m, 2 m) clamped flat 5 cm above a table.
rod = {
    "length": 2.0, "stiffness": {"kx": 1.0, "ky": 1.0, "kz": 1.0},
    "gravity": {"linear_density": 1.0, "vector": [0.0, 0.0, -1.0]},
    "base_quaternion": [np.sqrt(0.5), 0.0, np.sqrt(0.5), 0.0],
    "base_position": [0.0, 0.0, 0.05],
    "obstacles": [{"shape": "half_space", "point": [0, 0, 0], "normal": [0, 0, 1]}],
}
lying = softspine.solve(rod, n_elements=80)
lift_off = lying.contacts["arc_length"].min()
print(f"rod: lifts off the table at s = {lift_off:.3f} m "
      f"(small-deflection theory (72 EI h / w)^(1/4) = {(72 * 0.05) ** 0.25:.3f} m); "
      f"{len(lying.contacts['force'])} contacts, {lying.iterations} Newton steps, "
      f"{lying.solve_time * 1e3:.2f} ms")

fig = plt.figure(figsize=(11, 5.2))
ax = fig.add_subplot(1, 2, 1, projection="3d")
plot_obstacles([ball], ax)
plot_backbone(free.solution, ax, nodes=False, color="0.6", lw=1.5, ls="--",
              label="free answer (through the ball)")
plot_backbone(ik.solution, ax, label="answer among obstacles")
plot_contacts(ik.solution, ax, scale=0.02)
ax.plot(*target, "kx", ms=10, label="target")
ax.view_init(elev=10, azim=-90)
ax.legend(loc="lower left", fontsize=8)
ax.set_title("3 sections, 30 g: around a ball")
ax2 = fig.add_subplot(1, 2, 2)
p = lying.positions
ax2.fill_between([-0.05, 2.05], -0.01, 0.0, color="0.8", label="table")
ax2.plot(p[:, 0], p[:, 2], "-o", ms=2, label="heavy rod")
c = lying.contacts
ax2.quiver(c["point"][:, 0], c["point"][:, 2], 0 * c["force"], c["force"],
           color="tab:red", scale=2.0, width=0.004, label="contact forces")
ax2.set_xlabel("x [m]")
ax2.set_ylabel("z [m]")
ax2.set_title("a heavy rod lifted 5 cm off a table")
ax2.legend(fontsize=8)
fig.tight_layout()
out = sys.argv[1] if len(sys.argv) > 1 else "contact.png"
fig.savefig(out, dpi=110)
print(f"wrote {out}")
