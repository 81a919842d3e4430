"""A 3-section tendon-driven continuum robot with a tip load, and a magnetic
catheter steered by a uniform field, on one figure (needs matplotlib:
pip install 'softspine[plot]').

Run: python examples/tendons_and_magnets.py [out.png]
"""

from __future__ import annotations

import sys

import matplotlib.pyplot as plt
import numpy as np

import softspine
from softspine.plotting import plot_backbone

# The tendon robot: a 0.3 m nitinol-like backbone, three sections of 0.1 m,
# three tendons a section at 120 degrees and 8 mm from the backbone, each
# anchored at its section's end; 20 g at the tip.
sections, radius = 3, 0.008
tendons = []
for section, tensions in enumerate([(12.0, 0.0, 0.0), (0.0, 0.0, 14.0), (0.0, 10.0, 0.0)]):
    for k, tension in enumerate(tensions):
        angle = np.deg2rad(90 + 120 * k + 40 * section)
        tendons.append(
            {
                "tension": tension,  # N
                "offset": [radius * np.cos(angle), radius * np.sin(angle)],  # m
                "end": 0.1 * (section + 1),  # m: anchored at the section's end
            }
        )
robot = {
    "length": 0.3,
    "stiffness": {"E": 60e9, "G": 23e9, "diameter": 0.0015},
    "gravity": {"linear_density": 0.05, "vector": [0, 0, -9.81]},
    "base_quaternion": [1, 0, 0, 0],  # pointing up
    "tip_force": [0, 0, -0.02 * 9.81],
    "tendons": tendons,
}
bent = softspine.solve(robot, n_elements=30, scheme="fe4", check=True)
print(f"tendon robot: tip at {np.round(bent.tip_position, 4)} m, stable={bent.stable}")

# The catheter: 0.2 m, soft, a magnetised last quarter and a tip magnet, in a
# 40 mT field along +x; the field turns the tip towards it.
catheter = {
    "length": 0.2,
    "stiffness": {"kx": 2e-4, "ky": 2e-4, "kz": 1.5e-4},
    "magnetization": [[0, 0, 0], [0, 0, 0], [0, 0, 0], [0, 0, 0.05]],  # A m^2 / m
    "tip_magnet": [0, 0, 0.05],  # A m^2, along the tip's axis
    "magnetic_field": [0.04, 0.0, 0.0],  # T
}
steered = softspine.solve(catheter, n_elements=32, scheme="fe4", check=True)
turn = np.degrees(np.arccos(np.clip(steered.rotation_matrices[-1][:, 2] @ [1, 0, 0], -1, 1)))
print(f"catheter: tip at {np.round(steered.tip_position, 4)} m, {turn:.1f} deg from the field")

fig = plt.figure(figsize=(10, 5))
left = fig.add_subplot(1, 2, 1, projection="3d")
plot_backbone(bent, left, label="3 sections, 9 tendons, 20 g")
left.set_title("tendon-driven robot")
left.legend()
right = fig.add_subplot(1, 2, 2, projection="3d")
plot_backbone(softspine.solve({**catheter, "magnetic_field": [0, 0, 0]}), right, label="no field")
plot_backbone(steered, right, label="40 mT along +x")
right.set_title("magnetic catheter")
right.legend()
out = sys.argv[1] if len(sys.argv) > 1 else "tendons_and_magnets.png"
fig.savefig(out, dpi=90)
plt.close(fig)
print(f"written {out}")
