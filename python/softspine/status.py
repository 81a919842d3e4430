"""How a solve ended and what computed it: ``Solution.status``,
``IkResult.ending`` and ``Solution.scheme``.

All are string enums: a member equals its name (``sol.status == "converged"``
holds), prints as it, and the core (Rust) sets it. The members mirror the
core's ``Status`` and ``IkEnding``; a test checks that they agree.
"""

from __future__ import annotations

from enum import Enum


class _Name(str, Enum):
    """A string enum that prints as its value (``enum.StrEnum`` is 3.11+)."""

    def __str__(self) -> str:
        return str(self.value)

    def __format__(self, spec: str) -> str:
        return format(str(self.value), spec)


class Status(_Name):
    """How a solve ended. Only ``CONVERGED`` is an answer; every other ending
    carries the best state reached, its residual and a message."""

    CONVERGED = "converged"
    """The relative residual is below ``residual_tol``, the state is finite and
    every element turns within what the scheme resolves."""
    NOT_CONVERGED = "not_converged"
    """The methods stalled before the iteration budget ran out (the line search
    or the load continuation could not progress)."""
    ITERATION_LIMIT = "iteration_limit"
    """``max_iterations`` ran out before convergence."""
    TOLERANCE_NOT_MET = "tolerance_not_met"
    """Accuracy on demand stopped at its largest n with the error estimate above
    ``tol`` (the state is a converged equilibrium at that n)."""
    UNDERRESOLVED = "underresolved"
    """The discrete rod cannot follow the shape (an element turns by more than
    1 rad, or a held point is beyond what n elements reach): use more elements."""
    NUMERICAL_ERROR = "numerical_error"
    """The state or the residual is not finite (an overflow)."""
    INDETERMINATE = "indeterminate"
    """Not attempted: a held point at full reach has no well-defined reaction."""


class Scheme(_Name):
    """How a solution's nodes were computed: its discretisation."""

    FD2 = "fd2"
    """The seed's finite differences, second order."""
    FE4 = "fe4"
    """Quadratic elements with condensed internal nodes, fourth order."""
    RK4 = "rk4"
    """Shooting's integrator (``method="shooting"``), fourth order."""


class IkEnding(_Name):
    """Why an inverse solve ended."""

    REACHED = "reached"
    """The tip (and direction) is within the tolerance, on a stable equilibrium."""
    OUT_OF_REACH = "out_of_reach"
    """The closest tip found is limited by the robot, not by its drives' limits."""
    BOUNDS_ACTIVE = "bounds_active"
    """Drives at their limits hold the closest tip found back: muscles at their
    length limits, tendons slack or at ``max_tension``, the field at ``max_field``."""
    SOLVER_FAILURE = "solver_failure"
    """No stable equilibrium was found where the descent had to go."""
    ITERATION_LIMIT = "iteration_limit"
    """The iteration budget ran out while the miss was still shrinking."""
    LOAD_IGNORED = "load_ignored"
    """The geometric strategy's fit, applied to the loaded robot, misses."""
