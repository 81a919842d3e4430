"""The batch calls on a cluster: Ray, Dask, or any ``concurrent.futures``
executor.

``robot.forward_batch(..., executor=client)`` (and ``workspace``,
``inverse_batch``, ``softspine.solve_batch``) lands here. The batch is cut into
parts of ``part`` samples (a multiple of ``chunk``, so every part is solved
exactly as the same samples of a local batch: the results are identical to a
local run's), each part is one task that runs the local batch on its worker's
cores, and the parts are joined in order. ``executor`` is

* a Dask ``distributed.Client`` (or anything with ``submit`` returning futures
  with ``result()``, such as a ``concurrent.futures.ProcessPoolExecutor``);
* the ``ray`` module (after ``ray.init(...)``), or the context ``ray.init``
  returns.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
import numpy.typing as npt

from ._core import Robot, Scene, Scheme, _solve_batch
from .batch import BatchResult, IkBatchResult, concatenate, progress_callback
from .types import Method, SceneDict, SchemeName

__all__ = ["forward_batch", "inverse_batch", "solve_batch", "workspace"]

def _is_ray(executor: Any) -> bool:
    if getattr(executor, "__name__", None) == "ray":
        return True
    return type(executor).__module__.startswith("ray.")


def _run(
    executor: Any,
    task: Callable[..., Any],
    calls: list[tuple[Any, ...]],
    sizes: list[int],
    progress: Any,
) -> list[Any]:
    """Run ``task(*call)`` for every call on the executor; the results in
    order, reporting the samples of the finished tasks to ``progress``."""
    total = sum(sizes)
    report = progress_callback(progress)
    if _is_ray(executor):
        import ray

        remote = ray.remote(task)
        refs = [remote.remote(*call) for call in calls]
        size_of = {ref: size for ref, size in zip(refs, sizes, strict=True)}
        pending, done = list(refs), 0
        while pending:
            ready, pending = ray.wait(pending, num_returns=1, timeout=0.2)
            done += sum(size_of[r] for r in ready)
            if report:
                report(done, total)
        return list(ray.get(refs))
    if not callable(getattr(executor, "submit", None)):
        raise ValueError(
            "executor: expected a Dask Client, the ray module or a concurrent.futures "
            f"executor, got {type(executor).__name__}"
        )
    futures = [executor.submit(task, *call) for call in calls]
    while True:
        finished = [f.done() for f in futures]
        if report:
            report(sum(s for s, d in zip(sizes, finished, strict=True) if d), total)
        if all(finished):
            break
        time.sleep(0.05)
    return [f.result() for f in futures]


def _cuts(count: int, part: int) -> list[tuple[int, int]]:
    return [(start, min(start + part, count)) for start in range(0, count, part)] or [(0, 0)]


# The tasks: top-level functions (picklable), each a local batch on its worker.


def _forward_task(
    robot: Robot, actuations: Any, load: Any, options: dict[str, Any]
) -> BatchResult:
    return robot.forward_batch(actuations, load, progress=False, **options)


def _workspace_task(
    robot: Robot, count: int, load: Any, first: int, options: dict[str, Any]
) -> BatchResult:
    return robot.workspace(count, load, first=first, progress=False, **options)


def _inverse_task(
    robot: Robot, targets: Any, load: Any, options: dict[str, Any]
) -> IkBatchResult:
    return robot.inverse_batch(targets, load, progress=False, **options)


def _solve_task(scenes: list[Scene], settings: Any, options: dict[str, Any]) -> BatchResult:
    from .batch import solve_batch

    return solve_batch(scenes, settings, progress=False, **options)


def _options(**values: Any) -> dict[str, Any]:
    return {k: v for k, v in values.items() if v is not None}


def forward_batch(
    robot: Robot,
    actuations: npt.ArrayLike | None = None,
    load: float | dict[str, Any] | None = None,
    *,
    executor: Any,
    tensions: npt.ArrayLike | None = None,
    field: npt.ArrayLike | None = None,
    insertion: npt.ArrayLike | None = None,
    shapes: bool | None = None,
    warm_start: bool | None = None,
    threads: int | None = None,
    chunk: int | None = None,
    progress: Any = None,
    part: int | None = None,
) -> BatchResult:
    """``Robot.forward_batch`` on ``executor`` (see the module's documentation)."""
    # The core reads every argument as a local batch would, and cuts it.
    chunk, part = robot._forward_batch(
        actuations, load, tensions=tensions, field=field, insertion=insertion, shapes=shapes,
        warm_start=warm_start, threads=threads, chunk=chunk, part=part, plan=True,
    )  # fmt: skip
    named = (("actuations", actuations), ("tensions", tensions), ("field", field),
             ("insertion", insertion))
    given = {
        name: np.asarray(a, dtype=np.float64) for name, a in named if a is not None
    }
    count = len(next(iter(given.values())))
    options = _options(shapes=shapes, warm_start=warm_start, threads=threads, chunk=chunk)
    cuts = _cuts(count, part)
    calls = []
    for a, b in cuts:
        drives = {name: x[a:b] for name, x in given.items() if name != "actuations"}
        k = given["actuations"][a:b] if "actuations" in given else None
        calls.append((robot, k, load, {**options, **drives}))
    parts = _run(executor, _forward_task, calls, [b - a for a, b in cuts], progress)
    return concatenate(parts)


def workspace(
    robot: Robot,
    samples: int,
    load: float | dict[str, Any] | None = None,
    *,
    executor: Any,
    seed: int = 0,
    first: int = 0,
    shapes: bool | None = None,
    threads: int | None = None,
    chunk: int | None = None,
    progress: Any = None,
    part: int | None = None,
) -> BatchResult:
    """``Robot.workspace`` on ``executor``: each task draws its own samples
    (sample ``i`` from the seed and ``i``), the same as a local run's."""
    chunk, part = robot._workspace(
        samples, load, seed=seed, first=first, shapes=shapes, threads=threads, chunk=chunk,
        part=part, plan=True,
    )  # fmt: skip
    options = _options(seed=seed, shapes=shapes, threads=threads, chunk=chunk)
    cuts = _cuts(int(samples), part)
    calls = [(robot, b - a, load, int(first) + a, options) for a, b in cuts]
    parts = _run(executor, _workspace_task, calls, [b - a for a, b in cuts], progress)
    return concatenate(parts)


def inverse_batch(
    robot: Robot,
    targets: npt.ArrayLike,
    load: float | dict[str, Any] | None = None,
    *,
    executor: Any,
    reference: npt.ArrayLike | None = None,
    direction: npt.ArrayLike | None = None,
    settings: Any = None,
    pretension: npt.ArrayLike | None = None,
    orientation: Any = None,
    threads: int | None = None,
    chunk: int | None = None,
    progress: Any = None,
    part: int | None = None,
) -> IkBatchResult:
    """``Robot.inverse_batch`` on ``executor``."""
    chunk, part = robot._inverse_batch(
        targets, load, reference, direction, settings, pretension=pretension,
        orientation=orientation, threads=threads, chunk=chunk, part=part, plan=True,
    )  # fmt: skip
    t = np.asarray(targets, dtype=np.float64)
    options = _options(
        reference=reference,
        direction=direction,
        settings=settings,
        pretension=pretension,
        orientation=orientation,
        threads=threads,
        chunk=chunk,
    )
    cuts = _cuts(len(t), part)
    calls = [(robot, t[a:b], load, options) for a, b in cuts]
    parts = _run(executor, _inverse_task, calls, [b - a for a, b in cuts], progress)
    return concatenate(parts)


def solve_batch(
    scenes: Sequence[Scene | SceneDict | dict[str, Any]],
    settings: Any = None,
    *,
    executor: Any,
    n_elements: int | None = None,
    method: Method | None = None,
    scheme: SchemeName | Scheme | None = None,
    residual_tol: float | None = None,
    max_iterations: int | None = None,
    shapes: bool | None = None,
    threads: int | None = None,
    chunk: int | None = None,
    progress: Any = None,
    part: int | None = None,
) -> BatchResult:
    """``softspine.solve_batch`` on ``executor``."""
    scenes = [s if isinstance(s, Scene) else Scene(s) for s in scenes]
    chunk, part = _solve_batch(
        scenes, settings, n_elements=n_elements, method=method, scheme=scheme,
        residual_tol=residual_tol, max_iterations=max_iterations, shapes=shapes,
        threads=threads, chunk=chunk, part=part, plan=True,
    )  # fmt: skip
    options = _options(
        n_elements=n_elements,
        method=method,
        scheme=scheme,
        residual_tol=residual_tol,
        max_iterations=max_iterations,
        shapes=shapes,
        threads=threads,
        chunk=chunk,
    )
    cuts = _cuts(len(scenes), part)
    calls = [(scenes[a:b], settings, options) for a, b in cuts]
    parts = _run(executor, _solve_task, calls, [b - a for a, b in cuts], progress)
    return concatenate(parts)
