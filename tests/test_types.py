"""The types a checker uses (issue 29, item 6): ``softspine.types`` names
exactly what the core accepts, and mypy catches a misspelt key or method."""

from __future__ import annotations

import re
import textwrap
from typing import Any, get_args, get_type_hints

import pytest

import softspine
from softspine import IkEnding, Status, types

ROD = {"length": 1.0, "stiffness": {"kx": 1.0, "ky": 1.0, "kz": 1.0}}


def accepted_keys(make: Any) -> set[str]:
    """The keys the core lists when it refuses an unknown one."""
    with pytest.raises(ValueError, match="unknown key") as refusal:
        make()
    listed = re.search(r"expected one of: ([^)]*)\)", str(refusal.value))
    assert listed, str(refusal.value)
    return set(listed.group(1).split(", "))


def quoted(make: Any) -> set[str]:
    """The names the core lists, quoted, when it refuses an unknown one."""
    with pytest.raises(ValueError) as refusal:
        make()
    listed = str(refusal.value).split("expected")[1].split(", got")[0]
    return set(re.findall(r"'([^']+)'", listed))


def keys(typed: Any) -> set[str]:
    return set(typed.__annotations__)


UNKNOWN = {"not_a_key": 1}

CASES = {
    "SceneDict": (types.SceneDict, lambda: softspine.Scene({**ROD, **UNKNOWN})),
    "RobotDict": (types.RobotDict, lambda: softspine.Robot(UNKNOWN)),
    "StiffnessDict": (types.StiffnessDict, lambda: softspine.Scene({**ROD, "stiffness": UNKNOWN})),
    "GravityDict": (types.GravityDict, lambda: softspine.Scene({**ROD, "gravity": UNKNOWN})),
    "TipDict": (types.TipDict,
                lambda: softspine.Scene({**ROD, "tip": {"type": "clamped", **UNKNOWN}})),
    "SectionDict": (types.SectionDict, lambda: softspine.Scene({**ROD, "sections": [UNKNOWN]})),
    "PointLoadDict": (types.PointLoadDict,
                      lambda: softspine.Scene({**ROD, "point_loads": [UNKNOWN]})),
    "GuideDict": (types.GuideDict, lambda: softspine.Scene({**ROD, "guides": [UNKNOWN]})),
    "PortDict": (types.PortDict, lambda: softspine.Scene({**ROD, "ports": [UNKNOWN]})),
    "SceneTendonDict": (types.SceneTendonDict,
                        lambda: softspine.Scene({**ROD, "tendons": [UNKNOWN]})),
    "TendonDict": (types.TendonDict, lambda: softspine.Robot({"tendons": [UNKNOWN]})),
    "SectionPropertiesDict": (types.SectionPropertiesDict,
                              lambda: softspine.Robot({"section_properties": [UNKNOWN]})),
}


@pytest.mark.parametrize("name", CASES)
def test_each_typed_dict_has_the_keys_the_core_reads(name):
    typed, make = CASES[name]
    assert keys(typed) == accepted_keys(make)


def test_the_obstacle_dict_has_every_shapes_keys():
    shapes = get_args(get_type_hints(types.ObstacleDict)["shape"])
    assert set(shapes) == set(re.findall(r"\w+", str(pytest.raises(
        ValueError, softspine.Scene, {**ROD, "obstacles": [{"shape": "no_shape"}]}).value
    ).split("expected one of:")[1]))
    every = set()
    for shape in shapes:
        obstacle = {"shape": shape, **UNKNOWN}
        every |= accepted_keys(lambda o=obstacle: softspine.Scene({**ROD, "obstacles": [o]}))
    assert keys(types.ObstacleDict) == every


def test_the_literal_types_are_the_names_the_core_accepts():
    assert set(get_args(types.Method)) == quoted(lambda: softspine.solve(ROD, method="no"))
    assert set(get_args(types.SchemeName)) == quoted(lambda: softspine.solve(ROD, scheme="no"))
    assert set(get_args(types.Refine)) == quoted(
        lambda: softspine.solve(ROD, tol=1e-3, refine="no"))
    assert set(get_args(types.Strategy)) == quoted(
        lambda: softspine.Robot().inverse([0.0, 0.0, -0.9], strategy="no"))
    assert set(get_args(types.StatusName)) == {s.value for s in Status}
    assert set(get_args(types.IkEndingName)) == {e.value for e in IkEnding}


@pytest.mark.slow
def test_mypy_catches_a_misspelt_key_and_method(tmp_path):
    api = pytest.importorskip("mypy.api")
    script = tmp_path / "user.py"
    script.write_text(textwrap.dedent("""
        import softspine
        from softspine import SceneDict

        scene: SceneDict = {"length": 1.0, "stiffness": {"kx": 1.0, "ky": 1.0, "kz": 1.0},
                            "tip_froce": [0.0, 0.0, -1.0]}
        softspine.solve(scene, method="newtn")
        softspine.solve(scene, method="newton", scheme="fe4")
        robot = softspine.Robot({"sections": 3, "muscle_angels": [0, 120, 240]})
    """))
    out, _, status = api.run([str(script), "--no-incremental", "--cache-dir", str(tmp_path)])
    assert status == 1, out
    errors = [line for line in out.splitlines() if ": error:" in line]
    assert len(errors) == 2, out
    assert '"tip_froce"' in errors[0]
    assert "newtn" in errors[1] and '"method"' in errors[1]
    # The robot's dict is not annotated: its typo is for the core to refuse.
    with pytest.raises(ValueError, match="muscle_angels: unknown key"):
        softspine.Robot({"sections": 3, "muscle_angels": [0, 120, 240]})


def reference_names(kind: str) -> set[str]:
    from softspine._core import keys

    return {row["name"] for row in keys()[kind]}


def test_the_key_reference_names_exactly_the_keys_the_readers_take():
    # docs' key page (docs/hooks/keys.py) comes from the core's tables
    # (src/keys.rs): every key a reader accepts is there, and no other.
    scene, robot = reference_names("scene"), reference_names("robot")
    assert {n for n in scene if "." not in n} == accepted_keys(CASES["SceneDict"][1])
    assert {n for n in robot if "." not in n} == accepted_keys(CASES["RobotDict"][1])
    nested = {"stiffness": "StiffnessDict", "gravity": "GravityDict", "tip": "TipDict",
              "sections[]": "SectionDict", "point_loads[]": "PointLoadDict",
              "guides[]": "GuideDict", "ports[]": "PortDict", "tendons[]": "SceneTendonDict"}
    for parent, case in nested.items():
        listed = {n.split(".", 1)[1] for n in scene if n.startswith(parent + ".")}
        assert listed == accepted_keys(CASES[case][1]), parent
    assert {n.split(".", 1)[1] for n in scene if n.startswith("obstacles[].")} == {
        "shape", "friction"}
    for row in (*softspine._core.keys()["scene"], *softspine._core.keys()["robot"]):
        assert all(row[field] for field in ("unit", "default", "meaning")), row
