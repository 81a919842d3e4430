"""The golden set: answers of today's code that a refactor must keep.

A seeded list of cases covering every feature (loads, sections, tendons,
magnets, held tips, guides, both schemes, Levenberg-Marquardt, shooting,
accuracy on demand), robot inverse kinematics of every drive and a batch, with
the answers of the code that recorded them. ``tests/test_golden.py`` solves
every case again and compares (see there for the tolerances).

    python tools/golden.py                 # record tests/golden/golden.json.gz
    python tools/golden.py --check         # compare, print the largest changes
    python tools/golden.py --scenes K ...  # re-record these cases' answers only

Record anew only when a change of behaviour is intended, and say why in the
commit.
"""

from __future__ import annotations

import argparse
import gzip
import json
import math
from pathlib import Path
from typing import Any

import numpy as np

import softspine

OUT = Path(__file__).resolve().parent.parent / "tests" / "golden" / "golden.json.gz"
SCENES = 560
ROBOT_TARGETS = 12
TENDON_ROBOT = "examples/robots/tendon_robot.toml"
CATHETER = "examples/robots/magnetic_catheter.toml"


def _vec(rng: np.random.Generator, scale: float) -> list[float]:
    return [float(x) for x in rng.normal(size=3) * scale]


def random_scene(rng: np.random.Generator) -> tuple[dict[str, Any], dict[str, Any]]:
    """A valid scene of random features and the solve's keywords."""
    length = float(rng.choice([0.3, 1.0, 2.0]))
    k = float(10 ** rng.uniform(-1, 1))
    scene: dict[str, Any] = {"length": length}
    if rng.random() < 0.3:
        scene["stiffness"] = {"E": 50e9 * k, "G": 20e9 * k, "diameter": 0.003}
        k = 50e9 * k * math.pi * 0.003**4 / 64
    else:
        scene["stiffness"] = {"kx": k, "ky": k * float(rng.uniform(0.5, 2)),
                              "kz": k * float(rng.uniform(0.5, 1))}
    sections = int(rng.integers(1, 5))
    # Moderate loads: dimensionless parameters up to a few.
    force = k / length**2
    if rng.random() < 0.6:
        scene["rest_curvature"] = [[float(x) for x in rng.normal(size=2) * 2 / length]
                                   for _ in range(sections)]
    if rng.random() < 0.5:
        scene["gravity"] = {"linear_density": float(rng.uniform(0.05, 1)) * force / 9.81,
                            "vector": [0.0, 0.0, -9.81]}
    if rng.random() < 0.6:
        scene["tip_force"] = _vec(rng, 1.5 * force)
    if rng.random() < 0.3:
        scene["tip_moment"] = _vec(rng, 0.8 * k / length)
    if rng.random() < 0.2:
        scene["point_loads"] = [{"s": length / 2, "force": _vec(rng, force)}]
    kwargs: dict[str, Any] = {"n_elements": 20 if sections in (1, 2, 4) else 21}
    feature = rng.random()
    if feature < 0.15:
        own = [{"stiffness": {"kx": k * float(s), "ky": k * float(s), "kz": 0.7 * k * float(s)},
                "linear_density": 0.1 * force / 9.81} for s in rng.uniform(0.3, 3, size=sections)]
        if rng.random() < 0.5:
            fractions = rng.uniform(0.5, 1.5, size=sections)
            for p, f in zip(own, fractions / fractions.sum(), strict=True):
                p["length"] = float(f * length)
            scene["length"] = sum(p["length"] for p in own)
        scene["sections"] = own
        scene.setdefault("gravity", {"linear_density": 0.1 * force / 9.81,
                                     "vector": [0.0, 0.0, -9.81]})
        scene.setdefault("rest_curvature", [[0.0, 0.0]] * sections)
        scene["rest_curvature"] = (scene["rest_curvature"] * sections)[:sections]
        scene.pop("point_loads", None)
    elif feature < 0.3:
        scene["tendons"] = [{"tension": float(rng.uniform(0, 2)) * k / (0.02 * length),
                             "offset": [0.02 * length, 0.0], "twist": float(rng.normal())}]
    elif feature < 0.4:
        scene["magnetization"] = [[0.0, 0.0, 1.0]]
        scene["magnetic_field"] = [float(x) for x in rng.normal(size=3) * k / length]
        scene.pop("rest_curvature", None)
        kwargs["n_elements"] = 20
    elif feature < 0.5:
        scene["tip_force"] = _vec(rng, force)
        scene["tip_force_offset"] = [0.0, 0.05 * length, 0.1 * length]
    if rng.random() < 0.25 and "tendons" not in scene and "magnetization" not in scene:
        free = softspine.solve(scene, **kwargs)
        if free.converged:
            target = [float(x) for x in free.tip_position + rng.normal(size=3) * 0.02 * length]
            if rng.random() < 0.5:
                scene["tip"] = {"type": "pinned", "position": target}
            else:
                q = free.tip_quaternion
                scene["tip"] = {"type": "clamped", "position": target,
                                "quaternion": [float(x) for x in q]}
            scene.pop("tip_force", None)
            scene.pop("tip_moment", None)
            scene.pop("tip_force_offset", None)
            if rng.random() < 0.3:
                node = kwargs["n_elements"] // 2
                scene["guides"] = [{"s": float(free.arc_length[node]),
                                    "position": [float(x) for x in free.positions[node]]}]
    choice = rng.random()
    if choice < 0.3:
        kwargs["scheme"] = "fe4"
    elif choice < 0.4:
        plain = all(key not in scene for key in
                    ("tendons", "magnetization", "sections", "guides", "tip_force_offset"))
        if plain:
            kwargs["method"] = "shooting"
    elif choice < 0.45:
        kwargs["method"] = "lm"
    elif choice < 0.55:
        kwargs.pop("n_elements")
        kwargs["tol"] = float(rng.choice([1e-3, 1e-5, 1e-7]))
    return scene, kwargs


def solution_record(sol: softspine.Solution) -> dict[str, Any]:
    return {
        "status": str(sol.status),
        "stable": bool(sol.stable),
        "n_elements": int(sol.n_elements),
        "scheme": str(sol.scheme),
        "positions": sol.positions.tolist(),
        "energy": float(sol.energy),
        "residual_norm": float(sol.residual_norm),
        "tip_reaction_force": None if sol.tip_reaction_force is None
        else sol.tip_reaction_force.tolist(),
        "guide_reactions": sol.guide_reactions.tolist(),
    }


def scene_cases(count: int = SCENES, seed: int = 2026) -> list[dict[str, Any]]:
    """Random valid cases and their answers (a case the code refuses is drawn again)."""
    rng = np.random.default_rng(seed)
    cases: list[dict[str, Any]] = []
    while len(cases) < count:
        try:
            scene, kwargs = random_scene(rng)
            case = {"scene": scene, "kwargs": kwargs}
            case["answer"] = solution_record(solve_scene(case))
        except ValueError:
            continue
        cases.append(case)
    return cases


def robot_cases(seed: int = 7) -> list[dict[str, Any]]:
    """Inverse kinematics targets that each drive reaches: forward solves of
    random admissible drives."""
    rng = np.random.default_rng(seed)
    cases = []
    for name in ("default", TENDON_ROBOT, CATHETER):
        robot = softspine.Robot() if name == "default" else softspine.Robot.from_file(name)
        load = 0.0 if name == CATHETER else 0.02
        for _ in range(ROBOT_TARGETS):
            if robot.actuation_space == "tensions":
                tensions = rng.uniform(0, 20, size=len(robot.to_dict()["tendons"]))
                tip = robot.forward(tensions=tensions, load=load).tip_position
            elif robot.actuation_space == "field":
                b = rng.normal(size=3)
                b *= 0.8 * robot.to_dict()["max_field"] / np.linalg.norm(b)
                tip = robot.forward(field=b, load=load).tip_position
            else:
                kappa = robot.workspace(1, load, seed=int(rng.integers(1 << 30))).actuations[0]
                tip = robot.forward(kappa, load).tip_position
            cases.append({"robot": name, "load": load, "target": [float(x) for x in tip]})
    return cases


def solve_scene(case: dict[str, Any]) -> softspine.Solution:
    return softspine.solve(case["scene"], **case["kwargs"])


def solve_robot(case: dict[str, Any]) -> softspine.IkResult:
    name = case["robot"]
    robot = softspine.Robot() if name == "default" else softspine.Robot.from_file(name)
    return robot.inverse(case["target"], load=case["load"])


def ik_record(r: softspine.IkResult) -> dict[str, Any]:
    return {
        "reached": bool(r.reached),
        "ending": str(r.ending),
        "rest_curvature": r.rest_curvature.tolist(),
        "tensions": r.tensions.tolist(),
        "field": r.field.tolist(),
        "tip_position": r.tip_position.tolist(),
    }


def batch_record() -> dict[str, Any]:
    ws = softspine.Robot().workspace(128, 0.03, seed=11, progress=False)
    return {"tip_positions": ws.tip_positions.tolist(), "status": ws.status.tolist()}


def record() -> dict[str, Any]:
    scenes = scene_cases()
    robots = robot_cases()
    for case in robots:
        case["answer"] = ik_record(solve_robot(case))
    return {"scenes": scenes, "robots": robots, "batch": batch_record()}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--check", action="store_true", help="compare instead of recording")
    parser.add_argument("--robots", type=int, nargs="+", metavar="K",
                        help="re-record only these IK targets' answers (a change that a commit "
                             "explains), keeping every other recorded answer")
    parser.add_argument("--scenes", type=int, nargs="+", metavar="K",
                        help="re-record only these scene cases' answers (a change that a commit "
                             "explains), keeping every other recorded answer")
    args = parser.parse_args()
    if args.scenes:
        golden = json.loads(gzip.decompress(OUT.read_bytes()))
        for k in args.scenes:
            case = golden["scenes"][k]
            case["answer"] = solution_record(solve_scene(case))
            print(f"scene {k} ({case['kwargs']}): re-recorded")
        OUT.write_bytes(gzip.compress(json.dumps(golden).encode(), mtime=0))
        return
    if args.robots:
        golden = json.loads(gzip.decompress(OUT.read_bytes()))
        for k in args.robots:
            case = golden["robots"][k]
            case["answer"] = ik_record(solve_robot(case))
            print(f"IK target {k} ({case['robot']}, {case['target']}): re-recorded")
        OUT.write_bytes(gzip.compress(json.dumps(golden).encode(), mtime=0))
        return
    if args.check:
        golden = json.loads(gzip.decompress(OUT.read_bytes()))
        worst = 0.0
        other = []
        for k, case in enumerate(golden["scenes"]):
            sol = solve_scene(case)
            old = np.array(case["answer"]["positions"])
            same = (sol.n_elements, str(sol.scheme)) == (case["answer"]["n_elements"],
                                                         case["answer"]["scheme"])
            if same and old.shape == sol.positions.shape:
                worst = max(worst, float(np.abs(sol.positions - old).max()))
            else:
                other.append(k)
        print(f"largest change of a node: {worst:.3e} m")
        if other:
            print(f"another n or scheme: scenes {' '.join(map(str, other))}")
        return
    data = record()
    OUT.parent.mkdir(parents=True, exist_ok=True)
    OUT.write_bytes(gzip.compress(json.dumps(data).encode(), mtime=0))
    statuses: dict[str, int] = {}
    for case in data["scenes"]:
        statuses[case["answer"]["status"]] = statuses.get(case["answer"]["status"], 0) + 1
    print(f"{OUT}: {len(data['scenes'])} scenes {statuses}, {len(data['robots'])} IK targets")


if __name__ == "__main__":
    main()
