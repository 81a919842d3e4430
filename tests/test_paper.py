"""The seed paper's method (particle swarm, then LM over [q, F]) against Newton,
and the published system without its unit-norm condition, which collapses."""

from __future__ import annotations

import numpy as np
import pytest
from test_against_references import SCENES_3D

import softspine
from softspine.scenes import cantilever, end_moment

VALIDATION = {
    "cantilever alpha=1": cantilever(1.0),
    "cantilever alpha=3": cantilever(3.0),
    "cantilever alpha=10": cantilever(10.0),
    "quarter turn": end_moment(0.25),
    "full roll-up": end_moment(1.0),
    "piecewise arcs": {
        "length": 0.7,
        "stiffness": {"kx": 0.3, "ky": 0.5, "kz": 0.2},
        "rest_curvature": [[0.0, 2.0], [1.5, 0.0], [-1.0, -1.0], [2.0, 1.0]],
    },
    **SCENES_3D,
}


@pytest.mark.parametrize("name", list(VALIDATION))
def test_paper_agrees_with_newton(name):
    scene = VALIDATION[name]
    length = scene["length"]
    newton = softspine.solve(scene, n_elements=20, residual_tol=1e-12, check=True)
    paper = softspine.solve(scene, n_elements=20, method="paper", check=True)
    assert np.abs(paper.positions - newton.positions).max() < 1e-8 * length
    assert np.allclose(np.linalg.norm(paper.quaternions, axis=1), 1.0, atol=1e-12)


@pytest.mark.parametrize("name", ["cantilever alpha=3", "piecewise arcs"])
def test_literal_system_collapses(name):
    scene = VALIDATION[name]
    newton = softspine.solve(scene, n_elements=20)
    literal = softspine.solve(scene, n_elements=20, method="paper-literal")
    # Its own rows vanish, yet |q| drifts and the tip is far off: not an equilibrium.
    assert literal.residual_norm < 1e-10
    assert not literal.converged and "drifted" in literal.message
    drift = np.abs(np.linalg.norm(literal.quaternions, axis=1) - 1).max()
    assert drift > 0.05
    assert np.linalg.norm(literal.tip_position - newton.tip_position) > 0.05 * scene["length"]


def test_held_tips_by_the_paper_method():
    base = {"length": 1.0, "stiffness": {"kx": 1, "ky": 1, "kz": 1},
            "gravity": {"linear_density": 0.1, "vector": [0, 0, -9.81]}}
    for tip in ({"type": "pinned", "position": [0.4, 0.1, 0.8]},
                {"type": "clamped", "position": [0.4, 0.0, 0.8],
                 "quaternion": [0.9238795325112867, 0.0, 0.3826834323650898, 0.0]}):
        scene = {**base, "tip": tip}
        newton = softspine.solve(scene, n_elements=20, check=True)
        paper = softspine.solve(scene, n_elements=20, method="paper", check=True)
        assert np.allclose(paper.tip_reaction_force, newton.tip_reaction_force, atol=1e-8)
        assert np.abs(paper.positions - newton.positions).max() < 1e-8
        if tip["type"] == "clamped":
            assert np.allclose(paper.tip_reaction_moment, newton.tip_reaction_moment, atol=1e-8)


def test_seeded_swarm_is_deterministic():
    options = {"seed": 7, "particles": 16, "iterations": 20}
    a = softspine.solve(cantilever(3.0), method="paper", paper=options)
    b = softspine.solve(cantilever(3.0), method="paper", paper=options)
    assert np.array_equal(a.positions, b.positions)


def test_bad_paper_input():
    with pytest.raises(ValueError, match="^paper.swarm_size: unknown setting"):
        softspine.solve(cantilever(1.0), method="paper", paper={"swarm_size": 3})
    with pytest.raises(ValueError, match="^paper.chi:"):
        softspine.solve(cantilever(1.0), method="paper", paper={"chi": float("nan")})
    guided = {**cantilever(1.0), "guides": [{"s": 0.5, "position": [0.1, 0.0, 0.4]}]}
    with pytest.raises(ValueError, match="^method:"):
        softspine.solve(guided, method="paper")
