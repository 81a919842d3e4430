"""Sensitivities of an equilibrium and calibrated robot parameters, as
returned by ``Solver.sensitivity``, ``Robot.sensitivity`` and
``softspine.calibrate``. The work is done in the Rust core; these classes
only hold its arrays."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

if TYPE_CHECKING:
    from ._core import Robot, Solution

__all__ = ["Calibration", "Sensitivity"]


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
