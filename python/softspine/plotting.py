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

from ._core import read_obstacle

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
    if "ls" not in line and "linestyle" not in line:
        line["ls"] = "-"
    (drawn,) = ax.plot(r[:, 0], r[:, 1], r[:, 2], label=label, **line)
    colour = drawn.get_color()
    if nodes:
        ax.plot(r[:, 0], r[:, 1], r[:, 2], "o", ms=2.5, color=colour)
    ax.plot(*r[-1], "*", ms=12, color=colour)
    _equal_scales(ax, r, shown)
    return ax


def plot_obstacles(
    obstacles: Sequence[dict[str, Any]],
    ax: Axes3D | None = None,
    *,
    extent: float = 0.2,
    **surface: Any,
) -> Axes3D:
    """Draw obstacles (as a scene or robot lists them: dicts with a
    ``shape``) as translucent surfaces on 3D axes.

    A half-space is drawn as a square of side ``2 * extent`` (m) of its
    plane about its point; a sphere, capsule, cylinder and box as their
    surfaces; a lumen as the tube about its centreline; a mesh as its
    triangles. ``**surface`` goes to ``ax.plot_surface`` (``color``,
    ``alpha``) and ``ax.plot_trisurf``.
    """
    require_matplotlib()
    if ax is None:
        import matplotlib.pyplot as plt

        ax = plt.figure(figsize=(6.4, 6.4)).add_subplot(projection="3d")
    surface.setdefault("color", "0.6")
    surface.setdefault("alpha", 0.3)
    surface.setdefault("linewidth", 0)
    u, v = np.meshgrid(np.linspace(0.0, 2.0 * np.pi, 25), np.linspace(0.0, np.pi, 13))
    for obstacle in obstacles:
        if obstacle["shape"] == "mesh":
            # The core reads a mesh's file and places it.
            placed = read_obstacle(obstacle)
            vertices = np.asarray(placed["vertices"], dtype=float)
            ax.plot_trisurf(*vertices.T, triangles=np.asarray(placed["triangles"]),
                            **surface)
            continue
        for x, y, z in _obstacle_surfaces(obstacle, u, v, extent):
            ax.plot_surface(x, y, z, **surface)
    return ax


def _frame(axis: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors across the unit ``axis``."""
    other = np.array([1.0, 0.0, 0.0]) if abs(axis[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    e1 = np.cross(axis, other)
    e1 /= np.linalg.norm(e1)
    return e1, np.cross(axis, e1)


def _tube(a: np.ndarray, b: np.ndarray, ra: float, rb: float, u: np.ndarray
          ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The surface of a (conical) tube from ``a`` to ``b``."""
    axis = (b - a) / np.linalg.norm(b - a)
    e1, e2 = _frame(axis)
    t = np.linspace(0.0, 1.0, 2)[:, None]
    angles = u[0][None, :]
    radius = ra + (rb - ra) * t
    centre = a[None, None, :] + t[:, :, None] * (b - a)[None, None, :]
    ring = np.cos(angles)[..., None] * e1 + np.sin(angles)[..., None] * e2
    xyz = centre + radius[..., None] * ring
    return xyz[..., 0], xyz[..., 1], xyz[..., 2]


def _obstacle_surfaces(obstacle: dict[str, Any], u: np.ndarray, v: np.ndarray, extent: float
                       ) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    shape = obstacle["shape"]
    sphere = np.stack([np.cos(u) * np.sin(v), np.sin(u) * np.sin(v), np.cos(v)], axis=-1)
    if shape == "half_space":
        point = np.asarray(obstacle["point"], dtype=float)
        normal = np.asarray(obstacle["normal"], dtype=float)
        e1, e2 = _frame(normal / np.linalg.norm(normal))
        s, t = np.meshgrid([-extent, extent], [-extent, extent])
        xyz = point + s[..., None] * e1 + t[..., None] * e2
        return [(xyz[..., 0], xyz[..., 1], xyz[..., 2])]
    if shape == "sphere":
        xyz = np.asarray(obstacle["centre"], dtype=float) + obstacle["radius"] * sphere
        return [(xyz[..., 0], xyz[..., 1], xyz[..., 2])]
    if shape in ("capsule", "cylinder"):
        a = np.asarray(obstacle["a"], dtype=float)
        b = np.asarray(obstacle["b"], dtype=float)
        r = float(obstacle["radius"])
        out = [_tube(a, b, r, r, u)]
        if shape == "capsule":
            for end in (a, b):
                xyz = end + r * sphere
                out.append((xyz[..., 0], xyz[..., 1], xyz[..., 2]))
        return out
    if shape == "box":
        centre = np.asarray(obstacle["centre"], dtype=float)
        half = np.asarray(obstacle["half_extents"], dtype=float)
        q = np.asarray(obstacle.get("orientation", [1.0, 0.0, 0.0, 0.0]), dtype=float)
        w, x, y, z = q / np.linalg.norm(q)
        turn = np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                         [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                         [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])
        out = []
        for k in range(3):
            for sign in (-1.0, 1.0):
                i, j = [m for m in range(3) if m != k]
                s, t = np.meshgrid([-half[i], half[i]], [-half[j], half[j]])
                local = np.zeros(s.shape + (3,))
                local[..., k] = sign * half[k]
                local[..., i] = s
                local[..., j] = t
                xyz = centre + local @ turn.T
                out.append((xyz[..., 0], xyz[..., 1], xyz[..., 2]))
        return out
    if shape == "lumen":
        line = np.asarray(obstacle["centreline"], dtype=float)
        radius = np.broadcast_to(np.asarray(obstacle["radius"], dtype=float), len(line))
        return [_tube(line[k], line[k + 1], radius[k], radius[k + 1], u)
                for k in range(len(line) - 1)]
    raise ValueError(f"obstacles: unknown shape {shape!r}")


def contact_force_vectors(solution: Solution) -> np.ndarray:
    """Each contact's whole force on the rod, (k, 3), N: its normal force
    along the obstacle's normal plus its friction."""
    contacts = solution.contacts
    normal = np.asarray(contacts["normal"], dtype=float).reshape(-1, 3)
    force = np.asarray(contacts["force"], dtype=float)
    friction = np.asarray(contacts["friction"], dtype=float).reshape(-1, 3)
    return normal * force[:, None] + friction


def plot_contacts(solution: Solution, ax: Axes3D, *, scale: float | None = None,
                  **arrows: Any) -> Axes3D:
    """Draw a solution's contact forces on the rod as arrows at the points
    touched (the normal force and, with friction, the friction beside it),
    and its ports (a black dot each) with their forces on the rod; ``scale``
    (m per N) defaults to drawing the largest force a tenth of the rod's
    length."""
    contacts, ports = solution.contacts, solution.ports
    contact_forces = contact_force_vectors(solution)
    port_forces = np.asarray(ports["force"]).reshape(-1, 3)
    sizes = np.r_[np.linalg.norm(contact_forces, axis=1), np.linalg.norm(port_forces, axis=1)]
    if len(sizes) == 0:
        return ax
    if scale is None:
        scale = 0.1 * solution.length / max(float(sizes.max()), 1e-300)
    arrows.setdefault("color", "tab:red")
    if len(contact_forces):
        points = np.asarray(contacts["point"])
        ax.quiver(*points.T, *(scale * contact_forces).T, **arrows)
    if len(port_forces):
        points = np.asarray(ports["point"]).reshape(-1, 3)
        ax.scatter(*points.T, color="k", s=12)
        ax.quiver(*points.T, *(scale * port_forces).T, **arrows)
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
