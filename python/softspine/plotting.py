"""Plots of backbones (matplotlib, imported lazily: the solver does not need it)."""

from __future__ import annotations

from collections.abc import Sequence
from os import PathLike

import numpy as np


def plot_backbones(
    solutions: Sequence,
    path: str | PathLike,
    labels: Sequence[str] | None = None,
    title: str = "",
) -> None:
    """Write a 3D plot of one or more backbones (``Solution.positions``) to a PNG."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig = plt.figure(figsize=(6.4, 6.4))
    ax = fig.add_subplot(projection="3d")
    all_points = []
    for k, sol in enumerate(solutions):
        r = np.asarray(sol.positions)
        all_points.append(r)
        label = labels[k] if labels else None
        (line,) = ax.plot(r[:, 0], r[:, 1], r[:, 2], "-", lw=2.5, label=label)
        ax.plot(r[:, 0], r[:, 1], r[:, 2], "o", ms=2.5, color=line.get_color())
        ax.plot(*r[-1], "*", ms=12, color=line.get_color())
    ax.plot(0, 0, 0, "ks", ms=8, label="base")
    _finish(fig, ax, np.vstack(all_points), title, path)


def plot_tracking(
    points, results, path, title: str = "", geometric=None, backbones: int = 5
) -> None:
    """3D plot of a tracked trajectory: targets, reached tips, a few backbones and,
    if given, where the geometric (load-ignoring) actuation puts the tip."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    points = np.asarray(points)
    tips = np.array([r.tip_position for r in results])
    fig = plt.figure(figsize=(7.0, 6.4))
    ax = fig.add_subplot(projection="3d")
    for k in np.linspace(0, len(results) - 1, backbones).astype(int):
        r = results[k].solution.positions
        ax.plot(r[:, 0], r[:, 1], r[:, 2], "-", color="0.55", lw=1.5)
    ax.plot(*points.T, "o", ms=5, mfc="none", color="tab:blue", label="targets")
    ax.plot(*tips.T, ".", ms=4, color="tab:red", label="reached tips (load-aware IK)")
    if geometric is not None:
        g = np.array([r.tip_position for r in geometric])
        label = "tips of the geometric IK (load ignored)"
        ax.plot(*g.T, "x", ms=4, color="tab:orange", label=label)
    ax.plot(0, 0, 0, "ks", ms=8, label="base")
    _finish(fig, ax, np.vstack([points, tips, np.zeros((1, 3))]), title, path)


def _finish(fig, ax, points, title, path) -> None:
    """Equal scales on the three axes (a bent rod must look bent), labels, save."""
    import matplotlib.pyplot as plt

    centre = 0.5 * (points.max(axis=0) + points.min(axis=0))
    half = 0.5 * max(np.ptp(points, axis=0).max(), 1e-9)
    ax.set_xlim(centre[0] - half, centre[0] + half)
    ax.set_ylim(centre[1] - half, centre[1] + half)
    ax.set_zlim(centre[2] - half, centre[2] + half)
    ax.set_box_aspect((1, 1, 1))
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_zlabel("z [m]")
    if title:
        ax.set_title(title)
    ax.legend(loc="upper left", fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
