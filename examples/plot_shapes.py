"""Shapes of a rod under growing tip loads on one 3D plot (needs matplotlib:
pip install 'softspine[plot]').

Run: python examples/plot_shapes.py [out.png]
"""

from __future__ import annotations

import sys

import matplotlib.pyplot as plt

import softspine
from softspine.plotting import plot_backbone

ax = None
for load in (0.5, 1.5, 3.0, 6.0):
    scene = {"length": 1.0, "stiffness": {"kx": 1.0, "ky": 1.0, "kz": 1.0},
             "tip_force": [load, 0.0, -0.3 * load]}
    ax = plot_backbone(softspine.solve(scene, check=True), ax, label=f"P = {load} N")
assert ax is not None
ax.legend()
out = sys.argv[1] if len(sys.argv) > 1 else "shapes.png"
ax.figure.savefig(out, dpi=100)
plt.close(ax.figure)
print(f"written {out}")
