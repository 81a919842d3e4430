"""Saving and loading results: ``save(path)`` and ``load(path)`` on
``Solution``, ``IkResult``, ``BatchResult`` and ``IkBatchResult``, NPZ or
JSON by the file's suffix, every field of ``to_dict()`` and exactly (JSON
writes each float's shortest round-trip form); ``to_json()`` and
``from_json(text)`` give the same JSON as a string (``to_dict()`` holds
NumPy arrays, which ``json.dumps`` does not write).

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


def to_json(result: Saved) -> str:
    """Every field of ``result.to_dict()`` as JSON text (arrays as nested
    lists; each float's shortest round-trip form, so exactly)."""
    return json.dumps(_plain(result.to_dict()))


def save(result: Saved, path: str | PathLike[str]) -> None:
    """Write every field of ``result.to_dict()`` to ``path``: NPZ (``.npz``)
    or JSON (``.json``; arrays as nested lists)."""
    if _format(path) == ".npz":
        np.savez(path, **_flat(result.to_dict()))
        return
    with open(path, "w", encoding="utf-8") as f:
        f.write(to_json(result))


def from_json(text: str) -> dict[str, Any]:
    """The fields ``to_json`` wrote (a dict of lists), refused unless a JSON object."""
    if not isinstance(text, str):
        raise TypeError(f"text: expected a JSON string, got {type(text).__name__}")
    fields = json.loads(text)
    if not isinstance(fields, dict):
        raise ValueError(f"text: expected a JSON object, got {type(fields).__name__}")
    return fields


def read(path: str | PathLike[str]) -> dict[str, Any]:
    """The fields a ``save`` wrote to ``path`` (a ``to_dict()``, arrays as
    NumPy arrays from NPZ, as lists from JSON)."""
    if _format(path) == ".npz":
        with np.load(path) as data:
            return _nested(dict(data))
    with open(path, encoding="utf-8") as f:
        return from_json(f.read())


def _attach(kind: Any) -> None:
    """``kind.save(path)`` and ``kind.load(path)`` (by its ``from_dict``) on
    a class of the extension (the batch results define theirs)."""

    def save_method(self: Saved, path: str | PathLike[str]) -> None:
        save(self, path)

    def load(path: str | PathLike[str]) -> Any:
        return kind.from_dict(read(path))

    def to_json_method(self: Saved) -> str:
        return to_json(self)

    def from_json_text(text: str) -> Any:
        return kind.from_dict(from_json(text))

    save_method.__doc__ = save.__doc__
    load.__doc__ = f"The ``{kind.__name__}`` that ``save`` wrote to ``path``."
    to_json_method.__doc__ = to_json.__doc__
    from_json_text.__doc__ = f"The ``{kind.__name__}`` that ``to_json()`` wrote."
    kind.save = save_method
    kind.load = staticmethod(load)
    kind.to_json = to_json_method
    kind.from_json = staticmethod(from_json_text)


for _kind in (Solution, IkResult):
    _attach(_kind)
