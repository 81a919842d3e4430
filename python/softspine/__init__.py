"""softspine: fast, exact statics of soft continuum robots and elastic rods.

The backbone is a chain of unit quaternions at ``n + 1`` nodes (finite
differences); equilibrium comes from the discrete total potential and is solved
by Newton's method on a block-tridiagonal system (O(n) per iteration) in Rust.

>>> import softspine
>>> scene = {"length": 1.0, "stiffness": {"kx": 1.0, "ky": 1.0, "kz": 1.0},
...          "tip_force": [3.0, 0.0, 0.0]}
>>> sol = softspine.solve(scene, n_elements=40)
>>> sol.converged, round(float(sol.tip_position[0]), 3)
(True, 0.603)
"""

from __future__ import annotations

from os import PathLike
from typing import Any

import numpy.typing as npt

from . import files as _files  # noqa: F401  (save and load of Solution, IkResult)
from . import trajectories, types
from ._core import (
    Accuracy,
    IkEnding,
    IkResult,
    IkSettings,
    InverseSolver,
    PaperSettings,
    Robot,
    Scene,
    Scheme,
    Settings,
    Solution,
    Solver,
    SolverError,
    Status,
    __version__,
    read_obstacle,
)
from ._core import solve as _solve
from .batch import BatchResult, IkBatchResult, solve_batch
from .scenes import load_scene
from .sensitivity import Calibration, Sensitivity, calibrate
from .types import Method, Refine, RobotDict, SceneDict, SchemeName
from .viewer import view

__all__ = [
    "Accuracy",
    "BatchResult",
    "Calibration",
    "IkBatchResult",
    "IkEnding",
    "IkResult",
    "IkSettings",
    "InverseSolver",
    "PaperSettings",
    "Robot",
    "RobotDict",
    "Scene",
    "SceneDict",
    "Scheme",
    "Sensitivity",
    "Settings",
    "Solution",
    "Solver",
    "SolverError",
    "Status",
    "calibrate",
    "load_scene",
    "read_obstacle",
    "solve",
    "solve_batch",
    "trajectories",
    "types",
    "view",
    "__version__",
]


def solve(
    scene: Scene | SceneDict | dict[str, Any] | str | PathLike[str],
    settings: Settings | dict[str, Any] | None = None,
    *,
    n_elements: int | None = None,
    method: Method | None = None,
    scheme: SchemeName | Scheme | None = None,
    initial: Solution | npt.ArrayLike | None = None,
    accuracy: Accuracy | dict[str, Any] | None = None,
    tol: float | None = None,
    refine: Refine | None = None,
    residual_tol: float | None = None,
    max_iterations: int | None = None,
    check: bool = False,
    paper: PaperSettings | dict[str, Any] | None = None,
) -> Solution:
    """Solve the statics of ``scene``.

    Parameters
    ----------
    scene : Scene, dict, or path of a ``.json`` / ``.toml`` file
        What is solved (see ``softspine.Scene``).
    settings : Settings or dict, optional
        The solver's settings (``softspine.Settings``: every field with its unit
        and default); the keywords below override them.
    n_elements : int, optional
        Number of elements ``n``, a multiple of the number of sections. Default:
        the smallest multiple of the sections that is at least 20 (20 for one to
        four, five, ten or twenty sections, 21 for three). With accuracy on
        demand, the first ``n`` tried (the same default, raised to an ``n`` that
        resolves the rest shape).
    method : {"auto", "newton", "lm", "paper", "paper-literal", "shooting"}, optional
        ``"auto"`` (default): the core chooses, ``"shooting"`` for accuracy on
        demand where shooting models the scene (a free tip; no guides,
        tendons, magnets, sections of their own, contact; no ``scheme``
        given) and converges directly to a stable equilibrium,
        the fastest way to a tolerance, else ``"newton"``; the Solution's
        ``scheme`` says which (``"rk4"``: shooting). ``"newton"``: damped Newton with the
        O(n) block-tridiagonal solve and load continuation when a direct solve
        fails. ``"lm"``:
        Levenberg-Marquardt on the same residual (dense, for comparison).
        ``"paper"``: the seed paper's method, particle swarm then LM over the raw
        quaternions and nodal forces, with the unit-norm rows; ``"paper-literal"``:
        the published system without them (its |q| drifts: see the model's documentation).
        ``"shooting"``: classic RK4 on the Kirchhoff rod equations, one step an
        element, and Newton on the base wrench (fourth order at the nodes; no
        guides); the baseline of the report.
    scheme : {"fd2", "fe4"}, optional
        The discretisation of the backbone. ``"fd2"``: the seed's finite
        differences, second order. ``"fe4"``: quadratic elements of the rotation
        with two-point Gauss quadrature, fourth order at the nodes. Default:
        ``"fe4"`` for accuracy on demand below 3e-5 L (1e-6 L on a scene with
        held points; there it is the faster), ``"fd2"`` otherwise. The paper's
        method and shooting have their own.
    initial : Solution or array (n+1, 4), optional
        Warm start, e.g. the solution of a neighbouring scene: its ``n`` is the
        solve's unless ``n_elements`` is given (then they must agree); not with
        accuracy on demand. With friction a Solution is the last step of the
        history: the step starts from its rod where it stood (its base
        included); an array gives the rotations alone.
    accuracy : Accuracy or dict, optional
        Accuracy on demand (``softspine.Accuracy``): from a first resolving
        ``n`` and ``2n``, the estimated error of the whole backbone (the largest
        over the nodes, the difference of two solves over ``k^p - 1`` for the
        scheme's order ``p``) predicts the ``n`` that meets ``tol * L``, which is
        solved and checked in turn; by shooting each shot is estimated by a
        finer shot at ``2n`` (their difference over ``1 - 2^-p``: its own
        error) and is the answer where that meets the tolerance. The Solution
        carries ``error_estimate`` (m), the ``n_elements`` and the ``scheme``
        used.
    tol : float, optional
        Accuracy on demand with this ``tol`` (over ``accuracy``'s).
    refine : {"richardson"}, optional
        With ``tol``: return the Richardson-extrapolated tip
        ``r_kn + (r_kn - r_n) / (k^p - 1)`` as ``tip_position`` (``extrapolated``
        is then True).
    residual_tol : float, optional
        Tolerance in [1e-14, 1e-4] (default 1e-10) on the relative residual
        (the largest torque imbalance of a row over its own stiffness ``k_c / L``)
        and on the Newton step that certifies it (rad). Never below the
        residual's round-off floor ``8 eps (n + kappa L)`` (``kappa L``: the
        curvature scale of the loads).
    max_iterations : int, optional
        Iteration budget of the whole solve (default 500): the direct attempt,
        every load-continuation step and the Levenberg-Marquardt fallback share
        it, so ``Solution.iterations`` never exceeds it.
    check : bool
        Raise ``SolverError`` for any status other than "converged" (e.g.
        "iteration_limit", "tolerance_not_met", "underresolved").
    paper : PaperSettings or dict, optional
        Settings of the paper's method (``softspine.PaperSettings``); a dict's
        fields apply over ``settings.paper``.

    Returns
    -------
    Solution
        Positions, quaternions, forces, moments, curvatures, tip pose,
        reactions, ``status``, ``iterations``, ``residual_norm``, ``energy``,
        ``stable`` and ``solve_time``.

    Raises
    ------
    ValueError
        Bad input, naming the field (a scene key, a setting, an argument).
    SolverError
        With ``check=True``, a solve that did not converge.
    """
    return _solve(
        scene,
        settings,
        n_elements=n_elements,
        method=method,
        scheme=scheme,
        initial=initial,
        accuracy=accuracy,
        tol=tol,
        refine=refine,
        residual_tol=residual_tol,
        max_iterations=max_iterations,
        check=check,
        paper=paper,
    )
