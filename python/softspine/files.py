"""Saving and loading a solution: ``Solution.save(path)`` and
``Solution.load(path)``, NPZ or JSON by the file's suffix, every field of
``to_dict()`` and exactly (JSON writes each float's shortest round-trip
form)."""

from __future__ import annotations

import json
from os import PathLike, fspath
from typing import Any

import numpy as np

from ._core import Solution

FORMATS = (".npz", ".json")


def _format(path: str | PathLike[str]) -> str:
    """The file's format from its suffix, refused by name otherwise."""
    name = fspath(path)
    for suffix in FORMATS:
        if name.lower().endswith(suffix):
            return suffix
    raise ValueError(f"path: expected a file ending in {' or '.join(FORMATS)}, got {name!r}")


def save_solution(self: Solution, path: str | PathLike[str]) -> None:
    """Write every field of ``to_dict()`` to ``path``: NPZ (``.npz``; a field
    that is None is left out) or JSON (``.json``; arrays as nested lists)."""
    fields = self.to_dict()
    if _format(path) == ".npz":
        np.savez(path, **{k: v for k, v in fields.items() if v is not None})
        return
    plain: dict[str, Any] = {
        k: v.tolist() if isinstance(v, np.ndarray) else v for k, v in fields.items()
    }
    with open(path, "w", encoding="utf-8") as f:
        json.dump(plain, f)


def load_solution(path: str | PathLike[str]) -> Solution:
    """The solution that ``Solution.save`` wrote to ``path``."""
    if _format(path) == ".npz":
        with np.load(path) as data:
            return Solution.from_dict(dict(data))
    with open(path, encoding="utf-8") as f:
        return Solution.from_dict(json.load(f))


Solution.save = save_solution  # type: ignore[method-assign]
Solution.load = staticmethod(load_solution)  # type: ignore[method-assign]
