"""Look at an answer in 3D: ``softspine.view(result)`` builds an interactive
plotly figure (the backbone as a tube, a robot's disks and tendons, the tip
frame, obstacles, contact and port forces) and, given a path, writes it as a
self-contained HTML page (plotly.js inside: it opens offline, in any
browser). Needs plotly: ``pip install 'softspine[view]'``."""

from __future__ import annotations

from collections.abc import Sequence
from os import PathLike
from typing import Any

import numpy as np

from ._core import IkResult, Robot, Scene, Solution, read_obstacle
from .plotting import _obstacle_surfaces

#: The tube's sides, a disk's rim: points around the circle.
AROUND = 16


def require_plotly() -> Any:
    """plotly's graph objects, or ImportError naming the extra."""
    try:
        import plotly.graph_objects as go
    except ImportError as e:
        raise ImportError(
            "softspine.view needs plotly: pip install 'softspine[view]'"
        ) from e
    return go


def view(
    result: Solution | IkResult | Sequence[Solution | IkResult],
    path: str | PathLike[str] | None = None,
    *,
    robot: Robot | None = None,
    scene: Scene | dict[str, Any] | None = None,
    radius: float | None = None,
    title: str | None = None,
) -> Any:
    """An interactive 3D figure of one or more equilibria.

    Parameters
    ----------
    result : Solution, IkResult or a list of them
        What is drawn: each backbone as a tube, its tip frame (the material
        axes d1, d2, d3 in red, green, blue) and its contact and port forces
        (arrows, the largest a tenth of the rod's length).
    path : str or path, optional
        Write the figure there as a self-contained HTML page.
    robot : Robot, optional
        Draw its disks at the section ends, its tendons along their routes
        (or its muscles), and its obstacles.
    scene : Scene or dict, optional
        Draw its obstacles.
    radius : float, optional
        The tube's radius, m (default: the robot's or scene's ``radius``, or
        a hundredth of the length).
    title : str, optional

    Returns
    -------
    plotly.graph_objects.Figure
        ``fig.show()`` in a notebook, ``fig.write_html(path)``.
    """
    go = require_plotly()
    results = list(result) if isinstance(result, (list, tuple)) else [result]
    if not results:
        raise ValueError("result: nothing to draw")
    solutions = []
    for i, r in enumerate(results):
        if isinstance(r, IkResult):
            r = r.solution
        if not isinstance(r, Solution):
            raise TypeError(f"result[{i}]: expected a Solution or an IkResult, "
                            f"got {type(r).__name__}")
        solutions.append(r)
    fields: dict[str, Any] = {}
    if robot is not None:
        fields = robot.to_dict()
    elif scene is not None:
        fields = Scene(scene).to_dict()
    length = solutions[0].length
    tube = radius if radius is not None else fields.get("radius") or 0.01 * length
    fig = go.Figure()
    for k, sol in enumerate(solutions):
        name = f"backbone {k + 1}" if len(solutions) > 1 else "backbone"
        fig.add_trace(_tube_trace(go, sol, tube, name))
        for trace in _tip_frame(go, sol):
            fig.add_trace(trace)
        for trace in _forces(go, sol):
            fig.add_trace(trace)
        if robot is not None:
            for trace in _robot_parts(go, sol, fields, tube):
                fig.add_trace(trace)
    for trace in _obstacles(go, fields.get("obstacles") or [], length):
        fig.add_trace(trace)
    fig.update_layout(
        title=title,
        scene={"aspectmode": "data", "xaxis_title": "x [m]", "yaxis_title": "y [m]",
               "zaxis_title": "z [m]"},
        margin={"l": 0, "r": 0, "t": 40 if title else 0, "b": 0},
    )
    if path is not None:
        fig.write_html(path, include_plotlyjs=True, full_html=True)
    return fig


def _rings(centres: np.ndarray, frames: np.ndarray, radius: float) -> np.ndarray:
    """Points around each centre in its frame's d1-d2 plane: (k, AROUND, 3)."""
    angles = np.linspace(0.0, 2.0 * np.pi, AROUND, endpoint=False)
    around = np.stack([np.cos(angles), np.sin(angles)], axis=-1)  # (AROUND, 2)
    return centres[:, None, :] + radius * np.einsum("aj,kij->kai", around, frames[:, :, :2])


def _tube_trace(go: Any, sol: Solution, radius: float, name: str) -> Any:
    """The backbone as a tube of triangles, ring to ring."""
    rings = _rings(np.asarray(sol.positions), np.asarray(sol.rotation_matrices), radius)
    count = len(rings)
    vertices = rings.reshape(-1, 3)
    i, j, k = [], [], []
    for ring in range(count - 1):
        for a in range(AROUND):
            p, q = ring * AROUND + a, ring * AROUND + (a + 1) % AROUND
            i += [p, q]
            j += [q, q + AROUND]
            k += [p + AROUND, p + AROUND]
    return go.Mesh3d(x=vertices[:, 0], y=vertices[:, 1], z=vertices[:, 2], i=i, j=j, k=k,
                     color="steelblue", flatshading=False, name=name, showlegend=True)


def _tip_frame(go: Any, sol: Solution) -> list[Any]:
    """The tip's material axes, a tenth of the length each."""
    tip = np.asarray(sol.positions)[-1]
    frame = np.asarray(sol.rotation_matrices)[-1]
    size = 0.1 * sol.length
    traces = []
    for axis, color in zip(range(3), ("red", "green", "blue"), strict=True):
        end = tip + size * frame[:, axis]
        traces.append(go.Scatter3d(x=[tip[0], end[0]], y=[tip[1], end[1]], z=[tip[2], end[2]],
                                   mode="lines", line={"color": color, "width": 6},
                                   name=f"tip d{axis + 1}", showlegend=False))
    return traces


def _arrows(go: Any, points: np.ndarray, vectors: np.ndarray, name: str, color: str) -> Any:
    """Line segments from each point along its vector (one trace)."""
    xyz: list[list[float | None]] = [[], [], []]
    for p, v in zip(points, vectors, strict=True):
        for c in range(3):
            xyz[c] += [float(p[c]), float(p[c] + v[c]), None]
    return go.Scatter3d(x=xyz[0], y=xyz[1], z=xyz[2], mode="lines",
                        line={"color": color, "width": 5}, name=name)


def _forces(go: Any, sol: Solution) -> list[Any]:
    """Contact forces on the rod (normal and friction), port forces on it."""
    from .plotting import contact_force_vectors

    contacts, ports = sol.contacts, sol.ports
    contact_forces = contact_force_vectors(sol)
    port_forces = np.asarray(ports["force"], dtype=float).reshape(-1, 3)
    sizes = np.r_[np.linalg.norm(contact_forces, axis=1), np.linalg.norm(port_forces, axis=1)]
    if len(sizes) == 0 or sizes.max() <= 0.0:
        return []
    scale = 0.1 * sol.length / float(sizes.max())
    traces = []
    if len(contact_forces):
        traces.append(_arrows(go, np.asarray(contacts["point"]), scale * contact_forces,
                              "contact forces", "crimson"))
    if len(port_forces):
        points = np.asarray(ports["point"]).reshape(-1, 3)
        traces.append(_arrows(go, points, scale * port_forces, "port forces", "black"))
    return traces


def _section_ends(fields: dict[str, Any], length: float) -> np.ndarray:
    """Arc lengths of the section ends (equal sections unless each has a length)."""
    sections = int(fields.get("sections") or 1)
    own = [p.get("length") for p in fields.get("section_properties") or []]
    if len(own) == sections and all(x is not None for x in own):
        return np.cumsum(np.asarray(own, dtype=float))
    return length * np.arange(1, sections + 1) / sections


def _robot_parts(go: Any, sol: Solution, fields: dict[str, Any], tube: float) -> list[Any]:
    """Disks at the section ends and the tendons along their routes."""
    ends = _section_ends(fields, sol.length)
    starts = np.r_[0.0, ends[:-1]]
    tendons = list(fields.get("tendons") or [])
    if not tendons and fields.get("muscle_angles") is not None:
        # The muscles: along every section at their radius and angles.
        radius = float(fields["muscle_radius"])
        tendons = [{"offset": [radius * np.cos(np.radians(a)), radius * np.sin(np.radians(a))],
                    "section": len(ends), "name": "muscles"} for a in fields["muscle_angles"]]
    offsets = [np.asarray(t["offset"], dtype=float).reshape(-1, 2) for t in tendons]
    reach = max([float(np.linalg.norm(o, axis=1).max()) for o in offsets]
                + [float(fields.get("muscle_radius") or 0.0), 2.0 * tube])
    traces = []
    centres = np.asarray(sol.positions_at(ends)).reshape(-1, 3)
    frames = np.stack([_matrix(q) for q in np.asarray(sol.rotations_at(ends)).reshape(-1, 4)])
    rims = _rings(centres, frames, 1.3 * reach)
    for k, (centre, rim) in enumerate(zip(centres, rims, strict=True)):
        vertices = np.vstack([centre, rim])
        fan = np.arange(1, AROUND + 1)
        traces.append(go.Mesh3d(x=vertices[:, 0], y=vertices[:, 1], z=vertices[:, 2],
                                i=np.zeros(AROUND, dtype=int), j=fan, k=np.roll(fan, -1),
                                color="gray", opacity=0.6, name="disks", showlegend=k == 0,
                                legendgroup="disks"))
    for t, (tendon, offset) in enumerate(zip(tendons, offsets, strict=True)):
        last = int(tendon.get("section", len(ends)))
        twists = np.broadcast_to(np.asarray(tendon.get("twist", 0.0), dtype=float), (last,))
        points = []
        for section in range(last):
            rho = offset[min(section, len(offset) - 1)]
            s = np.linspace(starts[section], ends[section], 12)
            angle = twists[section] * (s - starts[section])
            turned = np.stack([np.cos(angle) * rho[0] - np.sin(angle) * rho[1],
                               np.sin(angle) * rho[0] + np.cos(angle) * rho[1],
                               np.zeros_like(s)], axis=-1)
            where = np.asarray(sol.positions_at(s)).reshape(-1, 3)
            turn = np.stack([_matrix(q) for q in np.asarray(sol.rotations_at(s)).reshape(-1, 4)])
            points.append(where + np.einsum("kij,kj->ki", turn, turned))
        path = np.vstack(points)
        name = tendon.get("name", "tendons")
        traces.append(go.Scatter3d(x=path[:, 0], y=path[:, 1], z=path[:, 2], mode="lines",
                                   line={"color": "darkorange", "width": 3}, name=name,
                                   showlegend=t == 0, legendgroup=name))
    return traces


def _matrix(q: np.ndarray) -> np.ndarray:
    """The rotation matrix of a unit quaternion [w, x, y, z]."""
    w, x, y, z = q / np.linalg.norm(q)
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


def _obstacles(go: Any, obstacles: list[dict[str, Any]], length: float) -> list[Any]:
    """Translucent surfaces (a half-space as a square of side L)."""
    u, v = np.meshgrid(np.linspace(0.0, 2.0 * np.pi, 25), np.linspace(0.0, np.pi, 13))
    traces = []
    for n, obstacle in enumerate(obstacles):
        shown = {"opacity": 0.35, "showscale": False, "name": f"obstacle {n}",
                 "colorscale": [[0, "gray"], [1, "gray"]]}
        if obstacle["shape"] == "mesh":
            placed = read_obstacle(obstacle)
            vertices = np.asarray(placed["vertices"], dtype=float)
            triangles = np.asarray(placed["triangles"], dtype=int)
            traces.append(go.Mesh3d(x=vertices[:, 0], y=vertices[:, 1], z=vertices[:, 2],
                                    i=triangles[:, 0], j=triangles[:, 1], k=triangles[:, 2],
                                    color="gray", opacity=0.35, name=f"obstacle {n}"))
            continue
        for x, y, z in _obstacle_surfaces(obstacle, u, v, 0.5 * length):
            traces.append(go.Surface(x=x, y=y, z=z, **shown))
    return traces
