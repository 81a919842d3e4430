"""Results of many solves at once, as arrays (see ``Robot.forward_batch``,
``Robot.inverse_batch``, ``Robot.workspace`` and ``softspine.solve_batch``).

The solves run in the Rust core on every core; these classes only hold what
they return, one row per sample, in the order of the input.
"""

from __future__ import annotations

import sys
import time
from dataclasses import dataclass, fields
from typing import Any

import numpy as np
import numpy.typing as npt

__all__ = ["BatchResult", "IkBatchResult", "TextProgress", "concatenate"]


def _dict(result: Any) -> dict[str, Any]:
    return {f.name: getattr(result, f.name) for f in fields(result)}


@dataclass(frozen=True, eq=False)
class BatchResult:
    """Forward equilibria of a batch, one row a sample.

    ``status`` holds each solve's ``softspine.Status`` name (``"converged"``,
    ...); ``positions`` and ``quaternions`` (scalar first) are the shapes when
    asked for (``shapes=True``), and ``actuations`` the rest curvature of each
    sample (m, 2) for a robot's batch, ``tensions`` and ``field`` its drives
    where they were given.
    """

    tip_positions: npt.NDArray[np.float64]
    """(N, 3), m."""
    tip_quaternions: npt.NDArray[np.float64]
    """(N, 4), scalar first."""
    status: npt.NDArray[np.str_]
    """(N,), the ``softspine.Status`` name of each solve."""
    stable: npt.NDArray[np.bool_]
    """(N,), whether each equilibrium is stable."""
    iterations: npt.NDArray[np.int64]
    """(N,)."""
    residual_norms: npt.NDArray[np.float64]
    """(N,)."""
    positions: npt.NDArray[np.float64] | None = None
    """(N, n + 1, 3), m, with ``shapes=True``."""
    quaternions: npt.NDArray[np.float64] | None = None
    """(N, n + 1, 4), with ``shapes=True``."""
    actuations: npt.NDArray[np.float64] | None = None
    """(N, m, 2), 1/m: the rest curvature of each sample (a robot's batch)."""
    tensions: npt.NDArray[np.float64] | None = None
    """(N, tendons), N: the tendon tensions of each sample (a tendon robot's batch)."""
    field: npt.NDArray[np.float64] | None = None
    """(N, 3), T: the field of each sample (a magnetic robot's batch)."""

    @property
    def converged(self) -> npt.NDArray[np.bool_]:
        """(N,), whether each solve converged."""
        return np.asarray(self.status == "converged")

    def __len__(self) -> int:
        return len(self.tip_positions)

    def to_dict(self) -> dict[str, Any]:
        """Every field (arrays or None): ``np.savez(path, **result.to_dict())``
        after dropping the None ones, or a DataFrame of the per-sample columns."""
        return _dict(self)


@dataclass(frozen=True, eq=False)
class IkBatchResult:
    """Inverse kinematics of a batch of targets, one row a target."""

    rest_curvature: npt.NDArray[np.float64]
    """(N, m, 2), 1/m: the actuation of each answer."""
    tip_positions: npt.NDArray[np.float64]
    """(N, 3), m: where the loaded equilibrium puts the tip."""
    tip_miss: npt.NDArray[np.float64]
    """(N,), m: distance to the target."""
    reached: npt.NDArray[np.bool_]
    """(N,), within the tolerance on a stable equilibrium."""
    ending: npt.NDArray[np.str_]
    """(N,), the ``softspine.IkEnding`` name of each solve."""
    iterations: npt.NDArray[np.int64]
    """(N,)."""
    tensions: npt.NDArray[np.float64] | None = None
    """(N, tendons), N: the tensions found (a tendon robot's batch)."""
    field: npt.NDArray[np.float64] | None = None
    """(N, 3), T: the field found (a magnetic robot's batch)."""

    def __len__(self) -> int:
        return len(self.tip_positions)

    def to_dict(self) -> dict[str, Any]:
        """Every field (arrays or None)."""
        return _dict(self)


def concatenate(parts: list[Any]) -> Any:
    """One result from the results of consecutive parts of a batch (in order)."""
    if not isinstance(parts, (list, tuple)):
        raise TypeError(f"parts: expected a list of batch results, got {type(parts).__name__}")
    if not parts:
        raise ValueError("parts: nothing to concatenate")
    kind = type(parts[0])
    for i, p in enumerate(parts):
        if not isinstance(p, (BatchResult, IkBatchResult)) or type(p) is not kind:
            expected = kind.__name__ if i else "BatchResult or IkBatchResult"
            raise TypeError(f"parts[{i}]: expected a {expected}, got {type(p).__name__}")
    merged: dict[str, Any] = {}
    for f in fields(kind):
        values = [getattr(p, f.name) for p in parts]
        if any(v is None for v in values):
            merged[f.name] = None
        else:
            merged[f.name] = np.concatenate(values)
    return kind(**merged)


class TextProgress:
    """A progress bar on standard error for long batches: it appears once a
    batch has run for ``after`` seconds (and only on a terminal unless
    ``always``), and ends with a newline."""

    def __init__(self, after: float = 2.0, always: bool = False) -> None:
        self.after = after
        self.always = always
        self.started = time.perf_counter()
        self.shown = False

    def __call__(self, done: int, total: int) -> None:
        elapsed = time.perf_counter() - self.started
        if not self.shown:
            if elapsed < self.after or not (self.always or sys.stderr.isatty()):
                return
            self.shown = True
        width = 30
        filled = width * done // max(total, 1)
        rate = done / elapsed if elapsed > 0 else 0.0
        sys.stderr.write(
            f"\r[{'#' * filled}{' ' * (width - filled)}] {done}/{total} ({rate:,.0f}/s)"
        )
        if done >= total:
            sys.stderr.write("\n")
        sys.stderr.flush()
