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
