"""A 3-section tendon-driven robot tracking the seed's circle with 20 g at its
tip, and a magnetic catheter steered around a circle by a uniform field: the
inverse kinematics in tension space and in field space, on one figure (needs
matplotlib: pip install 'softspine[plot]').

Run: python examples/tendons_and_magnets.py [out.png]
"""

from __future__ import annotations

import sys
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

import softspine
from softspine import trajectories
from softspine.plotting import plot_backbone

ROBOTS = Path(__file__).parent / "robots"

# The tendon robot (examples/robots/tendon_robot.toml): 0.3 m, pointing up,
# three tendons a section anchored at its end. The seed's circle, scaled to its
# length and turned with its base; 20 g at the tip.
robot = softspine.Robot.from_file(ROBOTS / "tendon_robot.toml")
circle = trajectories.circle(36, robot)
tracked = robot.track(circle, load=0.02)
times = np.array([r.time for r in tracked])
tensions = np.array([r.tensions for r in tracked])
print(f"tendon robot: {sum(r.reached for r in tracked)}/{len(circle)} points reached, "
      f"tip miss max {max(r.tip_miss for r in tracked):.1e} m, "
      f"IK per point median {np.median(times) * 1e3:.2f} ms; "
      f"tensions up to {tensions.max():.1f} N, "
      f"at most {np.max((tensions > 0).sum(1))} of 9 pulling")

# The catheter (examples/robots/magnetic_catheter.toml): 0.2 m, magnetised
# along its axis with a tip magnet. A field of 20 mT along x bends it; its
# tip's circle about the axis (the catheter is round) is what the field
# reaches as it turns, and the IK finds those fields back.
catheter = softspine.Robot.from_file(ROBOTS / "magnetic_catheter.toml")
bent = catheter.forward(field=[0.02, 0.0, 0.0])
x, _, z = bent.tip_position
angles = np.linspace(0, 2 * np.pi, 24, endpoint=False)
ring = np.column_stack([x * np.cos(angles), x * np.sin(angles), np.full_like(angles, z)])
steered = catheter.track(ring)
fields = np.array([r.field for r in steered])
print(f"catheter: {sum(r.reached for r in steered)}/{len(ring)} points reached, "
      f"|B| from {np.linalg.norm(fields, axis=1).min() * 1e3:.2f} "
      f"to {np.linalg.norm(fields, axis=1).max() * 1e3:.2f} mT; "
      f"a point off its reach: {catheter.inverse([0.05, 0.0, 0.15]).message}")

fig = plt.figure(figsize=(10, 5))
left = fig.add_subplot(1, 2, 1, projection="3d")
for k in range(0, len(tracked), 9):
    plot_backbone(tracked[k].solution, left, nodes=False, color="0.55")
left.plot(*circle.T, "o", ms=4, mfc="none", color="tab:blue", label="targets")
left.plot(*np.array([r.tip_position for r in tracked]).T, ".", ms=4, color="tab:red",
          label="tips (20 g load)")
left.set_title("tendon-driven robot: 3 sections, 9 tendons")
left.legend(loc="upper left", fontsize=8)
right = fig.add_subplot(1, 2, 2, projection="3d")
plot_backbone(catheter.forward(), right, nodes=False, color="0.3", label="no field")
for k in range(0, len(steered), 6):
    plot_backbone(steered[k].solution, right, nodes=False, color="0.55")
right.plot(*ring.T, "o", ms=4, mfc="none", color="tab:blue", label="targets")
right.quiver(*np.zeros((3, 4)), *(fields[::6].T / 0.02 * 0.05), color="tab:green",
             label="field (20 mT = 5 cm)")
right.set_title("magnetic catheter steered by a uniform field")
right.legend(loc="upper left", fontsize=8)
out = sys.argv[1] if len(sys.argv) > 1 else "tendons_and_magnets.png"
fig.savefig(out, dpi=90)
plt.close(fig)
print(f"written {out}")
