"""The contact reference itself (tests/contact_reference.py), checked before
any solver is checked against it: in the small-lift limit it meets the closed
forms of docs/model.md, and its error there falls as the small-deflection
theory's does (the square of the slope)."""

from __future__ import annotations

import pytest
from contact_reference import lifted_rod


@pytest.mark.parametrize(("horizontal", "factor", "share"), [(False, 24.0, 0.5),
                                                              (True, 72.0, None)])
def test_a_small_lift_meets_the_closed_forms(horizontal, factor, share):
    ei, w = 2.0, 3.0
    gaps = []
    for lift in (1e-3, 5e-4):
        a, force = lifted_rod(ei, w, lift, horizontal)
        exact = (factor * ei * lift / w) ** 0.25
        gaps.append(abs(a - exact) / exact)
        assert gaps[-1] < 1e-4
        if share is not None:
            assert force == pytest.approx(share * w * exact, rel=1e-4)
    # The theory's error is of the order of the slope squared, (h / a)^2:
    # halving h divides it by about 2^(3/2).
    assert 2.2 < gaps[0] / gaps[1] < 3.5


def test_a_large_lift_lifts_a_longer_part_than_the_linear_theory():
    # Large slopes: the rod's own geometry (the arc longer than its span)
    # moves the lift-off point; the reference still converges and keeps
    # the end's conditions.
    a, force = lifted_rod(1.0, 1.0, 0.3)
    linear = (24.0 * 0.3) ** 0.25
    assert a != pytest.approx(linear, rel=1e-3)
    assert 0.3 < a < 3.0 and force > 0.0
