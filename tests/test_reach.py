"""Reach what can be reached (issue 27): targets made by forward solves of each
robot's own random admissible drives (seeded; tools/reach_campaign.py) are
reachable by construction, so the inverse kinematics must reach them.

Before the restarts and the continuation in the target, the example tendon
robot reached 100 of 150 (38 ended `bounds_active` with tensions far inside
their range, 10 `iteration_limit`, 2 `out_of_reach`)."""

from __future__ import annotations

import pytest
from reach_campaign import reach, robots

ROBOTS = robots()


@pytest.mark.parametrize("name", sorted(ROBOTS))
def test_targets_of_admissible_drives_are_reached(name):
    robot, load = ROBOTS[name]
    found = reach(robot, load, 150, seed=27)
    assert len(found["targets"]) == 150, "every draw is a stable equilibrium"
    missed = [(i, str(r.ending), r.tip_miss)
              for i, r in enumerate(found["results"]) if not r.reached]
    assert len(missed) <= 1, missed
    for _, ending, miss in missed:
        # The one miss allowed is an iteration limit at the target's doorstep.
        assert ending == "iteration_limit" and miss < 1e-6 * robot.length, missed
