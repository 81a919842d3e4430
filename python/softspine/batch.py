"""Many solves at once: ``Robot.forward_batch``, ``Robot.workspace``,
``Robot.inverse_batch`` and ``softspine.solve_batch``, and their results as
arrays, one row per sample, in the order of the input.

The solves run in the Rust core on every core (the extension's
``_forward_batch`` and its kin return the results' fields). What is Python's
is here: the progress bar, the dispatch to a cluster (``executor=``, see
``softspine.distributed``) and the result dataclasses.
"""

from __future__ import annotations

import sys
from collections.abc import Callable, Sequence
from dataclasses import MISSING, dataclass, fields
from os import PathLike
from typing import TYPE_CHECKING, Any, TypeVar

import numpy as np
import numpy.typing as npt
from tqdm.auto import tqdm

from . import _core, files
from ._core import Robot

if TYPE_CHECKING:
    from ._core import IkSettings, Scene, Scheme, Settings, _Load
    from .types import Method, SceneDict, SchemeName

__all__ = [
    "BatchResult",
    "IkBatchResult",
    "BarProgress",
    "concatenate",
    "forward_batch",
    "inverse_batch",
    "progress_callback",
    "solve_batch",
    "workspace",
]

#: What ``progress=`` takes: None (a bar on a terminal once a batch has run
#: 2 s), True (a bar from the start), False (none) or ``progress(done, total)``.
Progress = bool | Callable[[int, int], object] | None


def _dict(result: Any) -> dict[str, Any]:
    return {f.name: getattr(result, f.name) for f in fields(result)}


R = TypeVar("R", bound="_Arrays")

#: The NumPy type of each array field of the batch results (what JSON's
#: lists are read back as).
_DTYPES: dict[str, type] = {"status": np.str_, "ending": np.str_, "stable": np.bool_,
                            "reached": np.bool_, "iterations": np.int64}


class _Arrays:
    """What the batch results share: their fields as a dict, and in files."""

    def to_dict(self) -> dict[str, Any]:
        """Every field (arrays or None), e.g. a DataFrame of the per-sample
        columns; ``save`` writes them to a file."""
        return _dict(self)

    @classmethod
    def from_dict(cls: type[R], data: dict[str, Any]) -> R:
        """The result of ``to_dict()`` (also what ``np.load`` gives back)."""
        return _from_dict(cls, data)

    def save(self, path: str | PathLike[str]) -> None:
        """Write every field to ``path``: NPZ (``.npz``) or JSON (``.json``)."""
        files.save(self, path)

    @classmethod
    def load(cls: type[R], path: str | PathLike[str]) -> R:
        """The result ``save`` wrote to ``path``."""
        return _from_dict(cls, files.read(path))

    def to_json(self) -> str:
        """Every field as JSON text (what ``save`` writes to a ``.json``)."""
        return files.to_json(self)

    @classmethod
    def from_json(cls: type[R], text: str) -> R:
        """The result ``to_json()`` wrote."""
        return _from_dict(cls, files.from_json(text))


def _from_dict(kind: Any, data: dict[str, Any]) -> Any:
    """A batch result of ``kind`` from its fields, each refused by name."""
    if not isinstance(data, dict):
        raise TypeError(f"data: expected a dict, got {type(data).__name__}")
    names = {f.name: f for f in fields(kind)}
    unknown = sorted(set(data) - set(names))
    if unknown:
        raise ValueError(f"{kind.__name__}.{unknown[0]}: unknown field (expected one of: "
                         f"{', '.join(names)})")
    values: dict[str, Any] = {}
    for name, f in names.items():
        value = data.get(name)
        if value is None:
            if f.default is MISSING:
                raise ValueError(f"{kind.__name__}.{name}: missing")
            continue
        values[name] = np.asarray(value, dtype=_DTYPES.get(name, np.float64))
    return kind(**values)


@dataclass(frozen=True, eq=False)
class BatchResult(_Arrays):
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
    insertion: npt.NDArray[np.float64] | None = None
    """(N,), m: the insertion of each sample (a robot with an
    ``insertion_range``; zero: forward batches take no insertion yet)."""

    @property
    def converged(self) -> npt.NDArray[np.bool_]:
        """(N,), whether each solve converged."""
        return np.asarray(self.status == "converged")

    def __len__(self) -> int:
        return len(self.tip_positions)



@dataclass(frozen=True, eq=False)
class IkBatchResult(_Arrays):
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
    insertion: npt.NDArray[np.float64] | None = None
    """(N,), m: the insertion found (a robot with an ``insertion_range``)."""

    def __len__(self) -> int:
        return len(self.tip_positions)



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


class BarProgress:
    """A progress bar for long batches (``tqdm``: a notebook widget in
    Jupyter, text on standard error elsewhere, with the rate and the time
    left): it appears once a batch has run for ``after`` seconds, and only
    on a terminal or in a notebook unless ``always``. Reports after the
    last are ignored, so the bar ends once."""

    def __init__(self, after: float = 2.0, always: bool = False) -> None:
        shown = always or _in_notebook() or sys.stderr.isatty()
        # Made when the batch starts, so that its rate and time left count
        # from there; the total comes with the first report.
        self.bar: Any = tqdm(total=None, unit="solve", dynamic_ncols=True,
                             delay=after, disable=not shown, file=sys.stderr)
        self.ended = False

    def __call__(self, done: int, total: int) -> None:
        if self.ended:
            return
        self.bar.total = total
        self.bar.unit_scale = total >= 10_000  # 1.00M/1.00M, 45.2ksolve/s
        self.bar.update(done - self.bar.n)
        if done >= total:
            self.bar.close()
            self.ended = True


def _in_notebook() -> bool:
    """Whether ``tqdm.auto`` chose its notebook widget (Jupyter)."""
    return tqdm.__module__ != "tqdm.asyncio"


def progress_callback(progress: Progress) -> Callable[[int, int], object] | None:
    """The callable ``progress=`` asks for (see ``Progress``), or None."""
    if progress is None:
        return BarProgress()
    if progress is True:
        return BarProgress(after=0.0, always=True)
    if progress is False:
        return None
    if callable(progress):
        return progress
    raise ValueError(
        f"progress: expected None, a bool or a callable, got {type(progress).__name__}"
    )


def forward_batch(
    self: Robot,
    actuations: npt.ArrayLike | None = None,
    load: _Load = None,
    *,
    tensions: npt.ArrayLike | None = None,
    field: npt.ArrayLike | None = None,
    insertion: npt.ArrayLike | None = None,
    shapes: bool | None = None,
    warm_start: bool | None = None,
    threads: int | None = None,
    chunk: int | None = None,
    progress: Progress = None,
    executor: Any = None,
    part: int | None = None,
) -> BatchResult:
    """Forward statics of many actuations under one load, in Rust on every
    core without the GIL.

    Parameters
    ----------
    actuations
        The muscles' rest curvature of each sample, (samples, m, 2), 1/m.
        Optional for a tendon-driven or magnetic robot (straight muscles).
    load
        What the robot carries: a payload mass [kg] or a dict of ``mass``,
        ``tip_force`` [N], ``tip_moment`` [N m] (world frame) and
        ``point_loads``, the same for every sample.
    tensions
        A tendon-driven robot's tensions, (samples, tendons), N: each within
        ``[0, max_tension]``.
    field
        A magnetic robot's uniform field, (samples, 3), T, world frame: each
        within ``max_field``.
    insertion
        How far each sample's base moves along its tangent, (samples,), m
        (within ``insertion_range`` where the robot has one; default 0).
    shapes
        Keep every node's position and quaternion (default False).
    warm_start
        Start a solve from the last equilibrium of its chunk where the
        actuation is near (default True; random samples are solved cold).
    threads
        Worker threads (default every core; at most 4 a core).
    chunk
        Samples a worker solves in order (default 64). The answers depend on
        it, never on the thread count.
    progress
        None (a bar on a terminal once the batch has run 2 s), True (a bar
        from the start), False (none) or a callable ``progress(done, total)``.
    executor
        A Dask ``Client``, the ``ray`` module (after ``ray.init``) or a
        ``concurrent.futures`` executor: the batch runs in tasks of ``part``
        samples, with the results of a local run (``softspine.distributed``).
    part
        Samples a task on ``executor`` (a multiple of ``chunk``; default 32
        chunks).

    Returns
    -------
    BatchResult
        One row a sample; the drives given are kept (``actuations``,
        ``tensions``, ``field``). Ctrl-C stops the batch (KeyboardInterrupt).
    """
    if executor is not None:
        from . import distributed

        return distributed.forward_batch(
            self, actuations, load, executor=executor, tensions=tensions, field=field,
            insertion=insertion, shapes=shapes, warm_start=warm_start, threads=threads,
            chunk=chunk, progress=progress, part=part,
        )  # fmt: skip
    fields_ = self._forward_batch(
        actuations, load, tensions=tensions, field=field, insertion=insertion, shapes=shapes,
        warm_start=warm_start, threads=threads, chunk=chunk,
        progress=progress_callback(progress), part=part,
    )  # fmt: skip
    return BatchResult(**fields_)


def workspace(
    self: Robot,
    samples: int,
    load: _Load = None,
    *,
    seed: int = 0,
    first: int = 0,
    shapes: bool | None = None,
    threads: int | None = None,
    chunk: int | None = None,
    progress: Progress = None,
    executor: Any = None,
    part: int | None = None,
) -> BatchResult:
    """The equilibria of ``samples`` random drives under one load, on every
    core: each muscle's length uniform over its range (``actuations``), a
    tendon-driven robot's tensions each over ``[0, max_tension]``
    (``tensions``), a magnetic robot's field uniform in the ball
    ``|B| <= max_field`` (``field``), and with an ``insertion_range`` the
    insertion uniform over it (``insertion``).

    Sample ``i`` is drawn from ``seed`` and ``first + i``, so a part of a
    larger workspace draws what the whole would. The other keywords are
    ``forward_batch``'s.
    """
    if executor is not None:
        from . import distributed

        return distributed.workspace(
            self, samples, load, executor=executor, seed=seed, first=first, shapes=shapes,
            threads=threads, chunk=chunk, progress=progress, part=part,
        )  # fmt: skip
    fields_ = self._workspace(
        samples, load, seed=seed, first=first, shapes=shapes, threads=threads, chunk=chunk,
        progress=progress_callback(progress), part=part,
    )  # fmt: skip
    return BatchResult(**fields_)


def inverse_batch(
    self: Robot,
    targets: npt.ArrayLike,
    load: _Load = None,
    reference: npt.ArrayLike | None = None,
    direction: npt.ArrayLike | None = None,
    settings: IkSettings | dict[str, Any] | None = None,
    *,
    pretension: npt.ArrayLike | None = None,
    orientation: Any = None,
    threads: int | None = None,
    chunk: int | None = None,
    progress: Progress = None,
    executor: Any = None,
    part: int | None = None,
) -> IkBatchResult:
    """Load-aware inverse kinematics of many targets (samples, 3), m, each on
    its own as ``Robot.inverse`` (the same ``reference``, ``direction`` or
    ``orientation``, ``settings`` and ``pretension`` for all), on every core.

    A chunk's solver starts each target from its last answer. The answers'
    drives are kept: ``rest_curvature`` always, ``tensions`` or ``field`` for
    a tendon-driven or magnetic robot. The other keywords are
    ``forward_batch``'s.
    """
    if executor is not None:
        from . import distributed

        return distributed.inverse_batch(
            self, targets, load, executor=executor, reference=reference, direction=direction,
            settings=settings, pretension=pretension, orientation=orientation, threads=threads,
            chunk=chunk, progress=progress, part=part,
        )  # fmt: skip
    fields_ = self._inverse_batch(
        targets, load, reference, direction, settings, pretension=pretension,
        orientation=orientation, threads=threads, chunk=chunk,
        progress=progress_callback(progress), part=part,
    )  # fmt: skip
    return IkBatchResult(**fields_)


def solve_batch(
    scenes: Sequence[Scene | SceneDict | dict[str, Any]],
    settings: Settings | dict[str, Any] | None = None,
    *,
    n_elements: int | None = None,
    method: Method | None = None,
    scheme: SchemeName | Scheme | None = None,
    residual_tol: float | None = None,
    max_iterations: int | None = None,
    shapes: bool | None = None,
    threads: int | None = None,
    chunk: int | None = None,
    progress: Progress = None,
    executor: Any = None,
    part: int | None = None,
) -> BatchResult:
    """Solve many scenes, each cold with ``settings``, in Rust on every core.

    ``shapes`` keeps the shapes only when every scene has the same number of
    nodes. The batch keywords are ``Robot.forward_batch``'s.
    """
    if executor is not None:
        from . import distributed

        return distributed.solve_batch(
            scenes, settings, executor=executor, n_elements=n_elements, method=method,
            scheme=scheme, residual_tol=residual_tol, max_iterations=max_iterations,
            shapes=shapes, threads=threads, chunk=chunk, progress=progress, part=part,
        )  # fmt: skip
    fields_ = _core._solve_batch(
        scenes, settings, n_elements=n_elements, method=method, scheme=scheme,
        residual_tol=residual_tol, max_iterations=max_iterations, shapes=shapes,
        threads=threads, chunk=chunk, progress=progress_callback(progress), part=part,
    )  # fmt: skip
    return BatchResult(**fields_)


# The native Robot's batch methods are these: the core solves, Python
# dispatches to a cluster and builds the result.
Robot.forward_batch = forward_batch  # type: ignore[method-assign]
Robot.workspace = workspace  # type: ignore[method-assign]
Robot.inverse_batch = inverse_batch  # type: ignore[method-assign]
