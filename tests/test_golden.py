"""The golden set (tools/golden.py): every recorded case solved again gives the
recorded answer. A refactor keeps behaviour; a change of behaviour re-records
the set in its own commit and says why.

Tolerances: the status, stability, n and scheme exactly; node positions within
1e-9 of the length (two converged answers of the same equilibrium differ by the
certification tolerance, 1e-10 rad, times the conditioning); an inverse solve
reaches the same targets with the same ending, its drives within 1e-6 of their
scale (a minimum-norm answer is unique only to the IK's tolerance).
"""

from __future__ import annotations

import gzip
import json

import numpy as np
import pytest

from golden import OUT, batch_record, solve_robot, solve_scene

GOLDEN = json.loads(gzip.decompress(OUT.read_bytes()))


def test_the_golden_set_covers_every_feature():
    scenes = [c["scene"] for c in GOLDEN["scenes"]]
    kwargs = [c["kwargs"] for c in GOLDEN["scenes"]]
    assert len(scenes) >= 500
    for key in ("rest_curvature", "gravity", "tip_force", "tip_moment", "point_loads",
                "sections", "tendons", "magnetization", "tip_force_offset", "tip", "guides"):
        assert sum(key in s for s in scenes) >= 10, key
    assert sum(k.get("scheme") == "fe4" for k in kwargs) >= 50
    assert sum(k.get("method") == "shooting" for k in kwargs) >= 10
    assert sum(k.get("method") == "lm" for k in kwargs) >= 10
    assert sum("tol" in k for k in kwargs) >= 30
    assert {c["robot"] for c in GOLDEN["robots"]} >= {"default"} and len(GOLDEN["robots"]) >= 30


@pytest.mark.parametrize("part", range(8))
def test_every_scene_gives_its_recorded_answer(part):
    cases = GOLDEN["scenes"][part::8]
    for case in cases:
        sol = solve_scene(case)
        old = case["answer"]
        label = json.dumps(case["scene"])[:200], case["kwargs"]
        assert (str(sol.status), bool(sol.stable)) == (old["status"], old["stable"]), label
        assert (sol.n_elements, str(sol.scheme)) == (old["n_elements"], old["scheme"]), label
        length = case["scene"]["length"]
        np.testing.assert_allclose(sol.positions, old["positions"], rtol=0,
                                   atol=1e-9 * length, err_msg=str(label))


def test_every_robot_target_gives_its_recorded_answer():
    for case in GOLDEN["robots"]:
        r = solve_robot(case)
        old = case["answer"]
        assert (bool(r.reached), str(r.ending)) == (old["reached"], old["ending"]), case
        for key in ("rest_curvature", "tensions", "field"):
            now, then = np.asarray(getattr(r, key)), np.asarray(old[key])
            scale = max(1.0, float(np.abs(then).max(initial=0.0)))
            np.testing.assert_allclose(now, then, rtol=0, atol=1e-6 * scale, err_msg=key)


def test_the_batch_gives_its_recorded_answer():
    now, then = batch_record(), GOLDEN["batch"]
    assert now["status"] == then["status"]
    np.testing.assert_allclose(now["tip_positions"], then["tip_positions"], rtol=0, atol=1e-9)
