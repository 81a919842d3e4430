"""Sensitivities of an equilibrium and calibrated robot parameters:
``Solver.sensitivity``, ``Robot.sensitivity`` and ``softspine.calibrate``.
The work is done in the Rust core (the extension's ``_sensitivity`` and
``_calibrate`` return the results' fields); these classes hold its arrays."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from . import _core
from ._core import Robot, Solver

if TYPE_CHECKING:
    from ._core import Solution, _Load

__all__ = ["Calibration", "Sensitivity", "calibrate"]


@dataclass(frozen=True, eq=False)
class Sensitivity:
    """Derivatives of the tip of an equilibrium, one column a parameter
    (by the implicit function theorem on the factored equilibrium system)."""

    parameters: list[str]
    """The parameters, one a column (``"rest_curvature[2][0]"``, ``"tip_force[1]"``, ...)."""
    tip_position: npt.NDArray[np.float64]
    """(3, k): d(tip position)/dp, m per unit of p."""
    tip_rotation: npt.NDArray[np.float64]
    """(3, k): the tip frame's turn, a world-frame rotation vector, rad per unit of p."""
    tip_reaction_force: npt.NDArray[np.float64] | None = None
    """(3, k): d(tip reaction force)/dp of a pinned or clamped tip, N per unit."""
    tip_reaction_moment: npt.NDArray[np.float64] | None = None
    """(3, k): d(tip reaction moment)/dp of a clamped tip, N m per unit."""
    exact: list[bool] | None = None
    """Per column, whether it comes from the terms' analytic derivatives
    (exact, in any units); ``False``: the parameter moves the mesh (a
    section's length) or the base, and the column is differenced at one and
    two unit-free steps, extrapolated (round-off, about 1e-12 relative)."""
    solution: Solution | None = None
    """The equilibrium (``Robot.sensitivity``)."""

    @property
    def pose(self) -> npt.NDArray[np.float64]:
        """(6, k): position rows over rotation rows (with ``"tip_wrench"``,
        the 6x6 tip compliance)."""
        return np.vstack([self.tip_position, self.tip_rotation])


@dataclass(frozen=True, eq=False)
class Calibration:
    """Robot parameters fitted to measured tip positions."""

    parameters: list[str]
    estimates: npt.NDArray[np.float64]
    """(k,): the least-squares estimates."""
    standard_errors: npt.NDArray[np.float64]
    """(k,): from the residual variance and (J^T J)^-1."""
    covariance: npt.NDArray[np.float64]
    """(k, k)."""
    residuals: npt.NDArray[np.float64]
    """(N, 3), m: measured minus model tip at the estimates."""
    rms: float
    """Root mean square of the residual components, m."""
    iterations: int
    converged: bool
    robot: Robot
    """The robot with the estimates."""
    message: str

    def summary(self) -> dict[str, Any]:
        """``{parameter: (estimate, standard error)}``."""
        return {
            p: (float(e), float(s))
            for p, e, s in zip(self.parameters, self.estimates, self.standard_errors, strict=True)
        }


def robot_sensitivity(
    self: Robot,
    rest_curvature: npt.ArrayLike | None = None,
    load: _Load = None,
    parameters: str | Sequence[str] | None = None,
    initial: Solution | npt.ArrayLike | None = None,
    *,
    tensions: npt.ArrayLike | None = None,
    field: npt.ArrayLike | None = None,
    insertion: float | None = None,
) -> Sensitivity:
    """The loaded equilibrium of an actuation (``.solution``) and its tip's
    sensitivity to named parameters.

    Parameters
    ----------
    rest_curvature, load, initial, tensions, field, insertion
        The actuation, load and start, as ``Robot.forward``.
    parameters
        A name or a list of names: ``"rest_curvature"``, ``"muscle_lengths"``
        (or one component, ``"muscle_lengths[2][0]"``), ``"tensions"`` (or
        ``"tensions[i]"``), ``"field"`` (or ``"field[c]"``), the load's
        ``"load.mass"`` (or ``"load"``), ``"load.tip_force"``,
        ``"load.tip_moment"``, ``"load.point_loads[j].force"`` and
        ``".moment"`` (each three columns, or one with ``[i]``),
        ``"insertion"`` (the base along its tangent, m), and any
        numeric field of ``Robot.to_dict()`` (``"stiffness.E"``,
        ``"linear_density"``, ``"disk_mass"``). Default: the robot's drive
        (``Robot.actuation_space``).

    Returns
    -------
    Sensitivity
        One column a parameter, in its own units (m per unit of it).
    """
    fields = self._sensitivity(
        rest_curvature, load, parameters, initial, tensions=tensions, field=field,
        insertion=insertion,
    )
    return Sensitivity(**fields)


def solver_sensitivity(self: Solver, parameters: str | Sequence[str]) -> Sensitivity:
    """Sensitivity of the last solve's equilibrium (solve first) to named
    parameters: paths in the scene's dict (``"tip_force[0]"``,
    ``"stiffness.kx"``, ``"gravity.linear_density"``,
    ``"rest_curvature[2][1]"``), ``"rest_curvature"`` (every section) or
    ``"tip_wrench"`` (the tip force and moment: the 6x6 tip compliance is
    ``.pose``). Free, pinned and clamped tips; by the implicit function
    theorem on the factored equilibrium system."""
    return Sensitivity(**self._sensitivity(parameters))


def calibrate(
    robot: Robot,
    actuations: npt.ArrayLike,
    measured_tips: npt.ArrayLike,
    parameters: str | Sequence[str],
    load: _Load = None,
    *,
    max_iterations: int | None = None,
    threads: int | None = None,
) -> Calibration:
    """Fit numeric fields of ``robot`` (``"stiffness.E"``, ``"linear_density"``,
    ``"disk_mass"``, ``"muscle_radius"``, ...) and of the load (``"load.mass"``,
    ``"load.tip_force"``, ``"load.tip_moment"``, ...: the names of
    ``Robot.sensitivity``) to tip positions (N, 3), m, measured at known
    actuations (N, m, 2), by Gauss-Newton with the sensitivities of every
    sample (on every core). An unknown tip force starts from ``load``'s (zero
    when not given): the measured tips sense it.

    Returns the estimates, their standard errors, the residuals and the
    fitted robot.
    """
    fields = _core._calibrate(
        robot, actuations, measured_tips, parameters, load,
        max_iterations=max_iterations, threads=threads,
    )  # fmt: skip
    return Calibration(**fields)


# The native classes' sensitivity methods are these: the core computes,
# Python builds the result.
Robot.sensitivity = robot_sensitivity  # type: ignore[method-assign]
Solver.sensitivity = solver_sensitivity  # type: ignore[method-assign]
