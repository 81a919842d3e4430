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

from . import trajectories
from ._core import IkResult, InverseSolver, Robot, Scene, Solution, SolverError, __version__
from ._core import solve as _solve
from .scenes import load_scene
from .status import IkEnding, Status

__all__ = [
    "IkEnding",
    "IkResult",
    "InverseSolver",
    "Robot",
    "Scene",
    "Solution",
    "SolverError",
    "Status",
    "load_scene",
    "solve",
    "trajectories",
    "__version__",
]


def solve(
    scene: Scene | dict | str | PathLike,
    n_elements: int | None = None,
    method: str | None = None,
    initial: Solution | None = None,
    tol: float | None = None,
    refine: str | None = None,
    residual_tol: float | None = None,
    max_iterations: int | None = None,
    check: bool = False,
    paper_options: dict | None = None,
) -> Solution:
    """Solve the statics of ``scene``.

    Parameters
    ----------
    scene : Scene, dict, or path of a ``.json`` / ``.toml`` file
        What is solved (see ``softspine.Scene``).
    n_elements : int, optional
        Number of elements ``n``, a multiple of the number of sections. Default:
        the smallest multiple of the sections that is at least 20 (20 for one to
        four, five, ten or twenty sections, 21 for three). With ``tol``, the first
        ``n`` tried (the same default, raised to an ``n`` that resolves the rest
        shape).
    method : {"newton", "lm", "paper", "paper-literal"}, optional
        ``"newton"``: damped Newton with the O(n) block-tridiagonal solve and load
        continuation when a direct solve fails (default). ``"lm"``:
        Levenberg-Marquardt on the same residual (dense, for comparison).
        ``"paper"``: the seed paper's method, particle swarm then LM over the raw
        quaternions and nodal forces, with the unit-norm rows; ``"paper-literal"``:
        the published system without them (its |q| drifts: see the README).
    initial : Solution or array (n+1, 4), optional
        Warm start, e.g. the solution of a neighbouring scene (fixed ``n`` only).
    tol : float, optional
        Accuracy on demand: ``n`` doubles until the estimated error of the whole
        backbone (the largest over the nodes, from the solves at n and 2n,
        second order) is below ``tol * L``; the Solution
        carries ``error_estimate`` (m) and the ``n_elements`` used.
    refine : {"richardson"}, optional
        With ``tol``: return the Richardson-extrapolated tip ``(4 r_2n - r_n)/3``
        as ``tip_position`` (``extrapolated`` is then True).
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
        "tolerance_not_met", "underresolved", "numerical_error").
    paper_options : dict, optional
        Settings of the paper's method: ``particles`` (40), ``iterations`` (60),
        ``chi`` (0.729), ``inertia`` (1.0), ``c1`` (2.05), ``c2`` (2.05), ``seed``
        (0), ``gauss_newton_iterations`` (20), ``lm_iterations`` (200), ``tol`` (1e-10).

    Returns
    -------
    Solution
        Positions, quaternions, forces, tip pose, reactions, ``converged``,
        ``iterations``, ``residual_norm``, ``energy`` and ``stable``.
    """
    return _solve(
        load_scene(scene),
        n_elements=n_elements,
        method=method,
        initial=initial,
        tol=tol,
        refine=refine,
        residual_tol=residual_tol,
        max_iterations=max_iterations,
        check=check,
        paper_options=paper_options,
    )
