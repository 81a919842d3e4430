"""An independent reference for friction: a straight rod lying on a rigid
floor with Coulomb friction, clamped at one end and pushed sideways along
the floor at the other, loaded in proportion from rest (so the slip of a
point is its displacement), in the small-deflection limit.

An Euler-Bernoulli beam (bending stiffness `ei`) of cubic Hermite elements
(displacement and slope at each node; sharing nothing with the solver's
quaternions), its friction lumped at the nodes: node i carries at most
`g_i = mu w h_i` (`h_i` its share of the length). The sideways displacement
`u` minimises the convex `1/2 u'Ku - F u_tip + sum g_i |u_i|` (`K` the
stiffness condensed onto the displacements). Its dual is a box-constrained
least squares: with `K = C C'`, the friction forces `f` minimise
`|C^-1 (b - f)|` over `|f_i| <= g_i` (`b` the push), which SciPy's bounded
variable least squares solves exactly; then `u = K^-1 (b - f)`. Nodes with
`|f_i| < g_i` stick, the others slide against their displacement: some of
them backwards, against the push, next to the forward slip zone."""

from __future__ import annotations

import numpy as np
from scipy.linalg import cholesky, solve_triangular
from scipy.optimize import lsq_linear


def pushed_along_a_floor(ei: float, weight: float, mu: float, length: float,
                         push: float, elements: int) -> np.ndarray:
    """The sideways displacement [m] of the nodes 1..elements (node 0 the
    clamp) of a rod pushed by `push` [N] at its free end, lying on a floor
    with friction coefficient `mu` under its weight `weight` [N/m]."""
    h = length / elements
    element = ei / h**3 * np.array([[12, 6 * h, -12, 6 * h],
                                    [6 * h, 4 * h * h, -6 * h, 2 * h * h],
                                    [-12, -6 * h, 12, -6 * h],
                                    [6 * h, 2 * h * h, -6 * h, 4 * h * h]])
    stiffness = np.zeros((2 * elements + 2, 2 * elements + 2))
    for e in range(elements):
        dofs = np.arange(2 * e, 2 * e + 4)
        stiffness[np.ix_(dofs, dofs)] += element
    stiffness = stiffness[2:, 2:]  # the clamp: no displacement, no slope
    u, slope = np.arange(0, 2 * elements, 2), np.arange(1, 2 * elements, 2)
    k = (stiffness[np.ix_(u, u)] - stiffness[np.ix_(u, slope)]
         @ np.linalg.solve(stiffness[np.ix_(slope, slope)], stiffness[np.ix_(slope, u)]))
    b = np.zeros(elements)
    b[-1] = push
    bound = mu * weight * h * np.ones(elements)
    bound[-1] *= 0.5
    c_inv = solve_triangular(cholesky(k, lower=True), np.eye(elements), lower=True)
    fit = lsq_linear(c_inv, c_inv @ b, bounds=(-bound, bound), method="bvls", tol=1e-15,
                     max_iter=10_000)
    assert fit.success, fit.message
    displacement: np.ndarray = np.linalg.solve(k, b - fit.x)
    return displacement


def check_step_sensitivity(scene: dict, start, force: np.ndarray, n: int, state,
                           atol: float = 2e-9) -> np.ndarray:
    """The tip's sensitivity to the tip force at the end of the step from
    `start` (a Solution) to `force`, against central differences of that
    step: whole solves from the same start to the force moved either way by
    1e-6 N, each keeping the friction state `state(solution)` the step
    ended in. Returns the sensitivity (3 x 3)."""
    import softspine

    solver = softspine.Solver({**scene, "tip_force": list(force)}, n_elements=n)
    sol = solver.solve(start)
    assert sol.converged, sol.message
    sens = solver.sensitivity(["tip_force[0]", "tip_force[1]", "tip_force[2]"]).tip_position
    delta = 1e-6
    for j in range(3):
        tips = []
        for sign in (1.0, -1.0):
            moved = np.array(force, dtype=float)
            moved[j] += sign * delta
            step = softspine.solve({**scene, "tip_force": list(moved)}, n_elements=n,
                                   initial=start)
            assert state(step) == state(sol)
            tips.append(step.tip_position)
        np.testing.assert_allclose(sens[:, j], (tips[0] - tips[1]) / (2.0 * delta), atol=atol)
    return sens
