"""Types a checker can use: the names the core accepts for ``method=``,
``scheme=``, ``strategy=`` and ``refine=`` as ``Literal`` types, and the
scene's and robot's dicts as ``TypedDict`` s.

Annotate a dict to have mypy (or pyright) check its keys and values::

    from softspine.types import SceneDict

    scene: SceneDict = {"length": 1.0, "stiffness": {"kx": 1, "ky": 1, "kz": 1},
                        "tip_froce": [0, 0, -1]}   # mypy: extra key "tip_froce"

Every key is optional here (``total=False``): the core says which are
required and refuses the rest by name at run time. Units are SI (m, N, kg,
Pa, rad unless a key says degrees); the guide's key reference gives each
key's unit, default and range. ``tests/test_types.py`` checks these keys
against the ones the core reads.
"""

from __future__ import annotations

from typing import Any, Literal, TypedDict

import numpy.typing as npt

__all__ = [
    "Method",
    "ObstacleDict",
    "Refine",
    "RobotDict",
    "SceneDict",
    "SchemeName",
    "StatusName",
    "IkEndingName",
    "Strategy",
]

#: ``solve(method=...)``.
Method = Literal["auto", "newton", "lm", "paper", "paper-literal", "shooting"]
#: ``solve(scheme=...)`` (``softspine.Scheme`` has the same values).
SchemeName = Literal["fd2", "fe4"]
#: ``Robot.inverse(strategy=...)``.
Strategy = Literal["equilibrium", "geometric"]
#: ``solve(refine=...)``.
Refine = Literal["richardson"]
#: The values of ``softspine.Status`` (a str enum: ``sol.status == "converged"``).
StatusName = Literal[
    "converged", "not_converged", "iteration_limit", "tolerance_not_met", "underresolved",
    "numerical_error", "indeterminate",
]
#: The values of ``softspine.IkEnding``.
IkEndingName = Literal[
    "reached", "out_of_reach", "bounds_active", "solver_failure", "iteration_limit",
    "load_ignored",
]

#: Three numbers (a list, a tuple or an array).
Vector = npt.ArrayLike
#: An orientation: a quaternion ``[w, x, y, z]``, a 3x3 rotation matrix or a
#: ``scipy.spatial.transform.Rotation``.
Orientation = Any


class StiffnessDict(TypedDict, total=False):
    """Bending and torsion: ``{kx, ky, kz}`` N m^2, or a round rod's
    ``{E, G, diameter}`` (Pa, Pa, m)."""

    kx: float
    ky: float
    kz: float
    E: float
    G: float
    diameter: float


class GravityDict(TypedDict, total=False):
    linear_density: float
    """kg/m."""
    vector: Vector
    """m/s^2, world frame."""


class TipDict(TypedDict, total=False):
    type: Literal["free", "pinned", "clamped"]
    position: Vector
    """m, world frame (pinned, clamped)."""
    quaternion: Orientation
    """The tip frame (clamped)."""


class SectionDict(TypedDict, total=False):
    length: float
    stiffness: StiffnessDict
    linear_density: float
    distributed_moment: Vector


class PointLoadDict(TypedDict, total=False):
    s: float
    """Arc length from the base, m (on a node)."""
    force: Vector
    moment: Vector


class GuideDict(TypedDict, total=False):
    s: float
    position: Vector


class PortDict(TypedDict, total=False):
    position: Vector
    axis: Vector
    friction: float


class SceneTendonDict(TypedDict, total=False):
    """A tendon of a scene, its tension given."""

    tension: float
    """N."""
    offset: Vector
    """``[x, y]`` m from the backbone, in the cross-section."""
    twist: float
    """rad/m: a helical route."""
    end: float
    """Arc length where it is anchored, m (default the tip)."""


class TendonDict(TypedDict, total=False):
    """A tendon of a robot (its tension is the drive's coordinate)."""

    offset: Vector
    """``[x, y]`` m from the backbone, or one such pair a section it runs through."""
    twist: float | list[float]
    section: int
    """The section (from 1) at whose end it is anchored."""


class ObstacleDict(TypedDict, total=False):
    """A rigid obstacle; the keys of its ``shape`` only (see the guide)."""

    shape: Literal["half_space", "sphere", "capsule", "cylinder", "box", "lumen", "mesh"]
    friction: float
    point: Vector
    normal: Vector
    centre: Vector
    radius: float | list[float]
    a: Vector
    b: Vector
    half_extents: Vector
    orientation: Orientation
    centreline: list[Vector]
    file: str
    vertices: list[Vector]
    triangles: list[list[int]]
    scale: float
    position: Vector
    free: bool


class SceneDict(TypedDict, total=False):
    """The keys of a scene (``softspine.Scene``, ``softspine.solve``)."""

    name: str
    length: float
    stiffness: StiffnessDict
    rest_curvature: list[list[float]]
    sections: list[SectionDict]
    distributed_force: Vector
    distributed_moment: Vector
    gravity: GravityDict
    tip_force: Vector
    tip_moment: Vector
    tip_force_offset: Vector
    base_quaternion: Orientation
    base_position: Vector
    tip: TipDict
    guides: list[GuideDict]
    point_loads: list[PointLoadDict]
    tendons: list[SceneTendonDict]
    magnetization: list[Vector]
    tip_magnet: Vector
    magnetic_field: Vector
    obstacles: list[ObstacleDict]
    ports: list[PortDict]
    radius: float


class SectionPropertiesDict(TypedDict, total=False):
    length: float
    stiffness: StiffnessDict
    linear_density: float
    disk_mass: float


class RobotDict(TypedDict, total=False):
    """The keys of a robot (``softspine.Robot``): its body, then one drive's
    (the muscles', the tendons' or the field's)."""

    length: float
    stiffness: StiffnessDict
    linear_density: float
    sections: int
    disk_mass: float
    gravity: Vector
    base_quaternion: Orientation
    base_position: Vector
    section_properties: list[SectionPropertiesDict]
    tool_mass: float
    tool_offset: Vector
    radius: float
    n_elements: int
    obstacles: list[ObstacleDict]
    ports: list[PortDict]
    insertion_range: Vector
    muscle_radius: float
    muscle_angles: Vector
    """Degrees, in the section's cross-section."""
    muscle_rest_length: float
    inflation_rate: float
    muscle_length_range: Vector
    tendons: list[TendonDict]
    max_tension: float
    magnetization: list[Vector]
    tip_magnet: Vector
    max_field: float
