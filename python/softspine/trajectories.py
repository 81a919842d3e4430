"""The seed paper's three trajectories for the default robot (hanging, 1 m):
a pentagram and a circle of radius 0.22 m in the plane z = -0.88 m, and a space
spiral of two turns rising from z = -0.93 to -0.83 m. 60 points each by default.
Given a robot, a trajectory is placed at it: scaled by its length and carried
to its base pose."""

from __future__ import annotations

import numpy as np

from ._core import Robot, trajectory_points

NAMES = ("pentagram", "circle", "spiral")


def pentagram(points: int = 60, robot: Robot | None = None) -> np.ndarray:
    """Five-pointed star {5/2}, walked edge by edge, shape (points, 3), m."""
    return trajectory_points("pentagram", points, robot)


def circle(points: int = 60, robot: Robot | None = None) -> np.ndarray:
    """Circle, shape (points, 3), m."""
    return trajectory_points("circle", points, robot)


def spiral(points: int = 60, robot: Robot | None = None) -> np.ndarray:
    """Space spiral, shape (points, 3), m."""
    return trajectory_points("spiral", points, robot)


def by_name(name: str, points: int = 60, robot: Robot | None = None) -> np.ndarray:
    """A trajectory by name: "pentagram", "circle" or "spiral"."""
    return trajectory_points(name, points, robot)
