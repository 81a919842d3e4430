"""Plots of backbones with matplotlib (``pip install softspine[plot]``).

``plot_backbone`` draws on axes you give it, or on new ones, and returns them:

>>> import softspine
>>> from softspine.plotting import plot_backbone
>>> sol = softspine.solve({"length": 1.0, "stiffness": {"kx": 1, "ky": 1, "kz": 1},
...                        "tip_force": [2.0, 0.0, 0.0]})
>>> ax = plot_backbone(sol, label="tip force")
>>> ax.figure.savefig("backbone.png")  # doctest: +SKIP

Nothing here selects a matplotlib backend: new axes come from ``pyplot`` (your
backend, so ``plt.show()`` works in a script or a notebook), and the files the
command line writes come from a bare ``Figure``, which needs no backend at all.
"""

from __future__ import annotations

from collections.abc import Sequence
from os import PathLike
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    from matplotlib.figure import Figure
    from mpl_toolkits.mplot3d.axes3d import Axes3D

    from ._core import IkResult, Solution


def require_matplotlib() -> None:
    """Raise ImportError naming the extra to install if matplotlib is missing."""
    try:
        import matplotlib  # noqa: F401
    except ImportError as e:  # pragma: no cover - the test extra has matplotlib
        raise ImportError(
            "softspine's plots need matplotlib: pip install 'softspine[plot]'"
        ) from e


def plot_backbone(
    solution: Solution,
    ax: Axes3D | None = None,
    *,
    label: str | None = None,
    nodes: bool = True,
    **line: Any,
) -> Axes3D:
    """Draw the backbone of ``solution`` (its node positions, m) on 3D axes.

    Parameters
    ----------
    solution : Solution
        What to draw: the line through ``solution.positions``, the nodes as dots
        (``nodes=True``) and the tip as a star.
    ax : Axes3D, optional
        Axes with ``projection="3d"`` to draw on; by default new axes on a new
        ``pyplot`` figure.
    label : str, optional
        Legend label of the line.
    **line
        Passed to ``ax.plot`` for the line (``color``, ``lw``, ``ls``, ...).

    Returns
    -------
    Axes3D
        The axes, with equal scales on x, y and z (a bent rod looks bent) that
        cover everything drawn on them so far.
    """
    require_matplotlib()
    if ax is None:
        import matplotlib.pyplot as plt

        ax = plt.figure(figsize=(6.4, 6.4)).add_subplot(projection="3d")
    shown = _shown(ax)
    r = np.asarray(solution.positions)
    line.setdefault("lw", 2.5)
    (drawn,) = ax.plot(r[:, 0], r[:, 1], r[:, 2], "-", label=label, **line)
    colour = drawn.get_color()
    if nodes:
        ax.plot(r[:, 0], r[:, 1], r[:, 2], "o", ms=2.5, color=colour)
    ax.plot(*r[-1], "*", ms=12, color=colour)
    _equal_scales(ax, r, shown)
    return ax


def _shown(ax: Axes3D) -> np.ndarray | None:
    """The corners of what the axes show, if anything is drawn on them yet."""
    if not ax.has_data():
        return None
    return np.array([ax.get_xlim(), ax.get_ylim(), ax.get_zlim()]).T


def _equal_scales(ax: Axes3D, points: np.ndarray, shown: np.ndarray | None = None) -> None:
    """Equal scales on the three axes, covering ``points`` and what the axes
    showed before (``shown``)."""
    points = np.asarray(points, dtype=float)
    if shown is not None:
        points = np.vstack([points, shown])
    lo, hi = points.min(axis=0), points.max(axis=0)
    centre = 0.5 * (lo + hi)
    half = 0.5 * max(float((hi - lo).max()), 1e-9)
    ax.set_xlim(centre[0] - half, centre[0] + half)
    ax.set_ylim(centre[1] - half, centre[1] + half)
    ax.set_zlim(centre[2] - half, centre[2] + half)
    ax.set_box_aspect((1, 1, 1))
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_zlabel("z [m]")


def _file_figure(size: tuple[float, float]) -> tuple[Figure, Axes3D]:
    """A figure for a file: a bare ``Figure`` (no pyplot, no backend)."""
    require_matplotlib()
    from matplotlib.figure import Figure

    fig = Figure(figsize=size)
    return fig, fig.add_subplot(projection="3d")


def plot_backbones(
    solutions: Sequence[Solution],
    path: str | PathLike[str],
    labels: Sequence[str] | None = None,
    title: str = "",
) -> None:
    """Write a 3D plot of one or more backbones to a PNG (the CLI's ``demo``)."""
    fig, ax = _file_figure((6.4, 6.4))
    for k, sol in enumerate(solutions):
        plot_backbone(sol, ax, label=labels[k] if labels else None)
    base = np.asarray(solutions[0].positions)[0]
    ax.plot(*base, "ks", ms=8, label="base")
    _save(fig, ax, title, path)


def plot_tracking(
    points: np.ndarray,
    results: Sequence[IkResult],
    path: str | PathLike[str],
    title: str = "",
    geometric: Sequence[IkResult] | None = None,
    backbones: int = 5,
) -> None:
    """A 3D plot of a tracked trajectory in a PNG: targets, reached tips, a few
    backbones and, if given, where the geometric (load-ignoring) actuation puts
    the tip (the CLI's ``track``)."""
    fig, ax = _file_figure((7.0, 6.4))
    points = np.asarray(points)
    tips = np.array([r.tip_position for r in results])
    for k in np.linspace(0, len(results) - 1, backbones).astype(int):
        plot_backbone(results[k].solution, ax, nodes=False, color="0.55", lw=1.5)
    ax.plot(*points.T, "o", ms=5, mfc="none", color="tab:blue", label="targets")
    ax.plot(*tips.T, ".", ms=4, color="tab:red", label="reached tips (load-aware IK)")
    if geometric is not None:
        g = np.array([r.tip_position for r in geometric])
        label = "tips of the geometric IK (load ignored)"
        ax.plot(*g.T, "x", ms=4, color="tab:orange", label=label)
    base = np.asarray(results[0].solution.positions)[0]
    ax.plot(*base, "ks", ms=8, label="base")
    _equal_scales(ax, np.vstack([points, tips, base[None, :]]), _shown(ax))
    _save(fig, ax, title, path)


def _save(fig: Figure, ax: Axes3D, title: str, path: str | PathLike[str]) -> None:
    if title:
        ax.set_title(title)
    ax.legend(loc="upper left", fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
