"""Load-aware inverse kinematics of the seed's 10-section pneumatic robot: the
actuation that puts the tip on a target with 30 g at the tip, then a circle.

Run: python examples/robot_inverse.py
"""

from __future__ import annotations

import numpy as np

import softspine

robot = softspine.Robot()  # 1 m, 10 sections, three muscles a section, hanging
result = robot.inverse([0.3, 0.1, -0.85], load=0.03)  # target in m, tip mass in kg
print(result)
print(f"ending: {result.ending}; muscle lengths of the first section "
      f"{result.muscle_lengths[0]} m")

# The same actuation without the load misses: the load matters.
unloaded = robot.forward(result.rest_curvature, load=0.0)
miss = np.linalg.norm(unloaded.tip_position - result.tip_position)
print(f"without the 30 g the tip would be {miss * 100:.1f} cm away")

# A trajectory: each point warm from the previous one.
points = softspine.trajectories.by_name("circle", 20)
track = robot.track(points, load=0.03)
print(f"circle: {sum(r.reached for r in track)}/{len(track)} reached, "
      f"largest miss {max(r.tip_miss for r in track):.1e} m")
