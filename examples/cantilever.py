"""A cantilever under a tip force: the solved tip against the closed form
(Bisshopp and Drucker), the moment on the base support, and accuracy on demand.

Run: python examples/cantilever.py
"""

from __future__ import annotations

import numpy as np

import softspine

# alpha = P L^2 / EI = 3: the tip deflects 0.60325 L sideways, 0.25442 L shorter.
scene = {
    "length": 1.0,  # m
    "stiffness": {"kx": 1.0, "ky": 1.0, "kz": 1.0},  # N m^2: bending x, y, torsion
    "tip_force": [3.0, 0.0, 0.0],  # N, world frame; the rod starts along +z
}
sol = softspine.solve(scene, n_elements=40, check=True)
print(sol)
print(f"tip deflection {sol.tip_position[0]:.5f} m (closed form 0.60325 m)")
print(f"moment on the base support {sol.moments[0]} N m")
print(f"largest curvature {np.abs(sol.curvatures).max():.3f} 1/m, solved in "
      f"{sol.solve_time * 1e6:.0f} us")

# Accuracy on demand: n doubles until the backbone's estimated error is below tol * L.
fine = softspine.solve(scene, tol=1e-6)
print(f"tol = 1e-6: n = {fine.n_elements}, estimated error {fine.error_estimate:.1e} m, "
      f"tip deflection {fine.tip_position[0]:.7f} m")
