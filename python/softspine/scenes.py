"""Loading scenes from dicts and files, and the scenes the demo and tests share."""

from __future__ import annotations

import math
from importlib import resources
from os import PathLike
from typing import Any

from ._core import Scene
from .types import SceneDict


def load_scene(scene: Scene | SceneDict | dict[str, Any] | str | PathLike[str]) -> Scene:
    """A ``Scene`` from a Scene, a dict, or the path of a ``.json``/``.toml`` file
    (``Scene(scene)``)."""
    return Scene(scene)


def demo_robot_scene() -> Scene:
    """The demo scene: a hanging 1 m, 10-section robot under its own weight and 30 g."""
    toml = resources.files("softspine") / "data" / "demo_robot.toml"
    return Scene.from_toml(toml.read_text(encoding="utf-8"))


def cantilever(alpha: float, length: float = 1.0, ei: float = 1.0) -> dict:
    """Bisshopp-Drucker cantilever: tip force ``alpha EI / L^2`` along +x, axis +z."""
    return {
        "name": f"cantilever alpha={alpha:g}",
        "length": length,
        "stiffness": {"kx": ei, "ky": ei, "kz": ei},
        "tip_force": [alpha * ei / length**2, 0.0, 0.0],
    }


def end_moment(turns: float, length: float = 1.0, ei: float = 1.0) -> dict:
    """Pure end moment about world y bending the rod into ``turns`` full circles."""
    return {
        "name": f"end moment {turns:g} turns",
        "length": length,
        "stiffness": {"kx": ei, "ky": ei, "kz": ei},
        "tip_moment": [0.0, 2.0 * math.pi * turns * ei / length, 0.0],
    }
