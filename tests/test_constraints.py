"""Pinned and clamped tips and guides through the Python API: reactions, exact
checks, refusals of ill-posed scenes and honest failures."""

from __future__ import annotations

import math

import numpy as np
import pytest
from contact_reference import clamped_pinned

import softspine

SCENE = {
    "length": 0.9,
    "stiffness": {"kx": 0.8, "ky": 1.1, "kz": 0.6},
    "rest_curvature": [[1.5, -0.5], [-1.0, 2.0]],
    "gravity": {"linear_density": 0.12, "vector": [0.0, 0.0, -9.81]},
    "tip_force": [0.7, -0.4, 0.3],
    "tip_moment": [0.05, -0.1, 0.02],
    "base_quaternion": [0.0, 1.0, 0.0, 0.0],
}


def held(tip, **changes):
    d = {**SCENE, "tip": tip, **changes}
    return {k: v for k, v in d.items() if v is not None}


@pytest.mark.parametrize("method", ["newton", "lm"])
def test_pinning_or_clamping_the_free_tip_returns_the_applied_loads(method):
    free = softspine.solve(SCENE, n_elements=20)
    pinned = softspine.solve(
        held({"type": "pinned", "position": free.tip_position.tolist()}, tip_force=None),
        n_elements=20,
        method=method,
        check=True,
    )
    assert np.allclose(pinned.tip_reaction_force, SCENE["tip_force"], atol=1e-9)
    assert pinned.tip_reaction_moment is None
    assert np.allclose(pinned.positions, free.positions, atol=1e-9)
    clamped = softspine.solve(
        held(
            {
                "type": "clamped",
                "position": free.tip_position.tolist(),
                "quaternion": free.tip_quaternion.tolist(),
            },
            tip_force=None,
            tip_moment=None,
        ),
        n_elements=20,
        method=method,
        check=True,
    )
    assert np.allclose(clamped.tip_reaction_force, SCENE["tip_force"], atol=1e-9)
    assert np.allclose(clamped.tip_reaction_moment, SCENE["tip_moment"], atol=1e-9)
    # The internal forces include the reaction: at the tip it is the reaction itself.
    assert np.allclose(clamped.forces[-1], SCENE["tip_force"], atol=1e-9)
    assert np.allclose(clamped.forces, free.forces, atol=1e-9)


def test_guide_reaction_is_the_jump_of_the_internal_force():
    free = softspine.solve(SCENE, n_elements=20)
    target = free.positions[8] + np.array([0.03, -0.02, 0.0])
    sol = softspine.solve(
        {**SCENE, "guides": [{"s": 0.36, "position": target.tolist()}]}, n_elements=20, check=True
    )
    assert np.allclose(sol.positions[8], target, atol=1e-10)
    (reaction,) = sol.guide_reactions
    # Whole-rod force balance: base force = tip force + weight + guide reaction.
    weight = 0.12 * 9.81 * 0.9 * np.array([0, 0, -1.0])
    assert np.allclose(sol.forces[0], np.array(SCENE["tip_force"]) + weight + reaction)
    assert sol.tip_reaction_force is None


def test_clamped_solution_is_an_equilibrium_of_the_free_rod_with_its_reactions():
    """Apply the reactions of a clamped solve as loads of a free solve: same shape."""
    tip = {"type": "clamped", "position": [0.3, 0.2, -0.6], "quaternion": [0.0, 0.8, 0.6, 0.0]}
    sol = softspine.solve(held(tip, tip_force=None, tip_moment=None), n_elements=30, check=True)
    assert sol.stable
    free = softspine.solve(
        {
            **SCENE,
            "tip_force": sol.tip_reaction_force.tolist(),
            "tip_moment": sol.tip_reaction_moment.tolist(),
        },
        n_elements=30,
        initial=sol,
    )
    assert free.converged
    assert np.allclose(free.positions, sol.positions, atol=1e-9)


@pytest.mark.parametrize(
    "scene,key,reason",
    [
        (
            held({"type": "clamped", "position": [0.1, 0, -0.5], "quaternion": [0, 1, 0, 0]}),
            "tip",
            "over-determines",
        ),
        (held({"type": "pinned", "position": [0.0, 0.5, -0.8]}), "tip.position", "unreachable"),
        (held({"type": "pinned"}), "tip.position", "missing"),
        (held({"type": "pinned", "position": [0, math.nan, 0]}), "tip.position[1]", "finite"),
        (
            held({"type": "clamped", "position": [0, 0, -0.5], "quaternion": [0.5, 0.5, 0, 0]}),
            "tip.quaternion",
            "unit",
        ),
        ({**SCENE, "guides": [{"s": 1.2, "position": [0, 0, -0.5]}]}, "guides[0].s", "inside"),
        ({**SCENE, "guides": [{"s": 0.0, "position": [0, 0, 0]}]}, "guides[0].s", "inside"),
        ({**SCENE, "guides": [{"s": 0.4, "position": [0, 0, -0.4]}]}, "guides[0].s", "node"),
        (
            {**SCENE, "guides": [{"s": 0.45, "position": [0.5, 0, 0]}]},
            "guides[0].position",
            "unreachable",
        ),
        (
            {
                **SCENE,
                "guides": [
                    {"s": 0.45, "position": [0, 0, -0.4]},
                    {"s": 0.54, "position": [0, 0, -0.2]},
                ],
            },
            "guides[1].position",
            "unreachable",
        ),
        (
            {
                **SCENE,
                "guides": [
                    {"s": 0.54, "position": [0, 0, -0.4]},
                    {"s": 0.45, "position": [0, 0, -0.3]},
                ],
            },
            "guides[1].s",
            "increasing",
        ),
        ({**SCENE, "guides": [{"s": 0.45}]}, "guides[0].position", "missing"),
    ],
)
def test_ill_posed_scenes_are_refused_before_iterating(scene, key, reason):
    with pytest.raises(ValueError) as info:
        softspine.solve(scene, n_elements=20)
    assert str(info.value).startswith(f"{key}:"), str(info.value)
    assert reason in str(info.value)


def test_target_at_full_reach_is_reported_not_solved():
    scene = held({"type": "pinned", "position": [0.9, 0.0, 0.0]}, tip_force=None)
    sol = softspine.solve(scene, n_elements=20)
    assert not sol.converged and sol.iterations == 0
    assert "full reach" in sol.message
    with pytest.raises(softspine.SolverError, match="full reach"):
        softspine.solve(scene, n_elements=20, check=True)


def test_buckling_needed_to_reach_a_target_on_the_axis():
    """No load, target straight ahead but closer than L: the rod must buckle. A
    small offset picks the direction; exactly on the axis (where it was reported
    as not converged: no step from the straight rod finds a buckled one) the
    held leg starts from a small bump in the base's softer plane (isotropic:
    towards its second director, +y here), never a straight rod. (Its plane is
    neutral: any turn about the axis is an equilibrium as well, so `stable`,
    which needs a positive definite reduced Hessian, is left to round-off.)"""
    base = {"length": 1.0, "stiffness": {"kx": 1, "ky": 1, "kz": 1}}
    sol = softspine.solve({**base, "tip": {"type": "pinned", "position": [0.01, 0, 0.9]}})
    assert sol.converged and sol.stable
    assert np.allclose(sol.tip_position, [0.01, 0, 0.9], atol=1e-10)
    # Compressive reaction, beyond the Euler load of a clamped-pinned column.
    assert sol.tip_reaction_force[2] < -20.19
    on_axis = softspine.solve({**base, "tip": {"type": "pinned", "position": [0, 0, 0.9]}})
    assert on_axis.converged, on_axis.message
    assert np.allclose(on_axis.tip_position, [0, 0, 0.9], atol=1e-10)
    assert np.abs(on_axis.positions[:, 0]).max() < 1e-12 and on_axis.positions[:, 1].min() > -1e-12
    assert on_axis.positions[:, 1].max() > 0.1
    # The clamped-pinned elastica (shooting, tests/contact_reference.py): the
    # pin's force along and across the axis, within n = 20's error (4.5e-2,
    # second order: test_a_column_pushed_along_its_line_buckles_as_...).
    ref = clamped_pinned(1.0, 1.0, 0.9)
    np.testing.assert_allclose(on_axis.tip_reaction_force[[2, 1]], ref["force"], atol=0.05)


def test_reaction_force_converges_at_second_order():
    """The pinned tip's reaction, n = 20 ... 160: successive differences fall by 4."""
    scene = held({"type": "pinned", "position": [0.25, -0.1, -0.75]}, tip_force=None)
    reactions = [
        softspine.solve(scene, n_elements=n, check=True).tip_reaction_force
        for n in (20, 40, 80, 160)
    ]
    diffs = [np.linalg.norm(b - a) for a, b in zip(reactions, reactions[1:], strict=False)]
    orders = np.log2(np.array(diffs[:-1]) / np.array(diffs[1:]))
    assert np.all((orders > 1.9) & (orders < 2.1)), (orders, diffs)
