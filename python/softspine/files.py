"""Saving and loading results: ``save(path)`` and ``load(path)`` on
``Solution``, ``IkResult``, ``BatchResult`` and ``IkBatchResult``, NPZ or
JSON by the file's suffix, every field of ``to_dict()`` and exactly (JSON
writes each float's shortest round-trip form).

A result's ``to_dict()`` may nest (an ``IkResult`` holds its solution's
dict): NPZ, which holds one level, keeps a nested field under its path
(``"solution/positions"``); a field that is None is left out (NPZ holds
none), and ``from_dict`` reads it as absent."""

from __future__ import annotations

import json
from os import PathLike, fspath
from typing import Any, Protocol

import numpy as np

from ._core import IkResult, Solution

FORMATS = (".npz", ".json")

#: Where NPZ keeps a nested field: ``"solution/positions"``.
SEPARATOR = "/"


class Saved(Protocol):
    def to_dict(self) -> dict[str, Any]: ...


def _format(path: str | PathLike[str]) -> str:
    """The file's format from its suffix, refused by name otherwise."""
    name = fspath(path)
    for suffix in FORMATS:
        if name.lower().endswith(suffix):
            return suffix
    raise ValueError(f"path: expected a file ending in {' or '.join(FORMATS)}, got {name!r}")


def _flat(fields: dict[str, Any], prefix: str = "") -> dict[str, Any]:
    """One level of ``path: value`` (NPZ), the None fields left out."""
    out: dict[str, Any] = {}
    for key, value in fields.items():
        if isinstance(value, dict):
            out.update(_flat(value, f"{prefix}{key}{SEPARATOR}"))
        elif value is not None:
            out[prefix + key] = value
    return out


def _nested(flat: dict[str, Any]) -> dict[str, Any]:
    """The dict ``_flat`` flattened."""
    out: dict[str, Any] = {}
    for path, value in flat.items():
        *parents, key = path.split(SEPARATOR)
        node = out
        for parent in parents:
            node = node.setdefault(parent, {})
        node[key] = value
    return out


def _plain(value: Any) -> Any:
    """Lists, numbers, strings and dicts (what ``json`` writes)."""
    if isinstance(value, dict):
        return {k: _plain(v) for k, v in value.items()}
    if isinstance(value, (np.ndarray, np.generic)):
        return value.tolist()
    return value


def save(result: Saved, path: str | PathLike[str]) -> None:
    """Write every field of ``result.to_dict()`` to ``path``: NPZ (``.npz``)
    or JSON (``.json``; arrays as nested lists)."""
    fields = result.to_dict()
    if _format(path) == ".npz":
        np.savez(path, **_flat(fields))
        return
    with open(path, "w", encoding="utf-8") as f:
        json.dump(_plain(fields), f)


def read(path: str | PathLike[str]) -> dict[str, Any]:
    """The fields a ``save`` wrote to ``path`` (a ``to_dict()``, arrays as
    NumPy arrays from NPZ, as lists from JSON)."""
    if _format(path) == ".npz":
        with np.load(path) as data:
            return _nested(dict(data))
    with open(path, encoding="utf-8") as f:
        fields: dict[str, Any] = json.load(f)
        return fields


def _attach(kind: Any) -> None:
    """``kind.save(path)`` and ``kind.load(path)`` (by its ``from_dict``) on
    a class of the extension (the batch results define theirs)."""

    def save_method(self: Saved, path: str | PathLike[str]) -> None:
        save(self, path)

    def load(path: str | PathLike[str]) -> Any:
        return kind.from_dict(read(path))

    save_method.__doc__ = save.__doc__
    load.__doc__ = f"The ``{kind.__name__}`` that ``save`` wrote to ``path``."
    kind.save = save_method
    kind.load = staticmethod(load)


for _kind in (Solution, IkResult):
    _attach(_kind)
