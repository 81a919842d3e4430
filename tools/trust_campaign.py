"""Counts of the trust campaign (issue 25), seeded, to rerun on any build.

    python tools/trust_campaign.py sections   # tight residual_tol, sections of own stiffness
    python tools/trust_campaign.py shooting   # shooting against Newton on random scenes
    python tools/trust_campaign.py tol        # accuracy on demand with located inputs
    python tools/trust_campaign.py threads    # one Solver shared by threads (set_* then solve)
    python tools/trust_campaign.py sensitivity  # sensitivities against whole solves, any units

Each prints what it counted; the regression tests keep the reproducers.
"""

from __future__ import annotations

import argparse
import copy
import math
import re
import threading
from collections import Counter
from typing import Any

import numpy as np

import softspine


def unit(rng: np.random.Generator) -> np.ndarray:
    v = rng.normal(size=3)
    return v / np.linalg.norm(v)


def sections(count: int) -> None:
    """Started from its own converged answer, a solve at residual_tol 1e-13 or
    1e-14 must converge again, on the same equilibrium."""
    rng = np.random.default_rng(1)
    failed = same = total = 0
    for _ in range(count):
        own = []
        for _ in range(int(rng.integers(2, 5))):
            k = 10 ** rng.uniform(-2, 2)
            own.append({"stiffness": {"kx": k, "ky": k * rng.uniform(0.5, 2), "kz": k * 0.7},
                        "linear_density": 10 ** rng.uniform(-2, 0)})
        scene = {"length": 1.0, "stiffness": {"kx": 1.0, "ky": 1.0, "kz": 0.7}, "sections": own,
                 "gravity": {"linear_density": 0.1, "vector": [0, 0, -9.81]},
                 "tip_force": list(rng.normal(size=3))}
        n = 8 * len(own)
        first = softspine.solve(scene, n_elements=n)
        if not first.converged:
            continue
        for tol in (1e-13, 1e-14):
            total += 1
            again = softspine.solve(scene, n_elements=n, residual_tol=tol, initial=first)
            failed += not again.converged
            same += again.converged and np.abs(again.positions - first.positions).max() < 1e-9
    print(f"{total} tight solves from the converged answer: {failed} not converged, "
          f"{same} on the same equilibrium")


def shooting_scene(rng: np.random.Generator) -> dict:
    """A scene shooting models: loads up to |F| L^2/EI = 50, |M| L/EI = 10,
    w L^3/EI = 50, rest curvature 10/L; free, pinned or clamped tips."""
    length = float(rng.choice([0.5, 1.0, 2.0]))
    ei = 10 ** rng.uniform(-1, 1)
    scene: dict = {"length": length,
                   "stiffness": {"kx": ei, "ky": ei * rng.uniform(0.3, 3),
                                 "kz": ei * rng.uniform(0.4, 1.5)}}
    held = rng.random()
    if held > 0.6:
        position = list(length * rng.uniform(0.1, 0.9) * unit(rng))
        if held < 0.8:
            scene["tip"] = {"type": "pinned", "position": position}
        else:
            q = rng.normal(size=4)
            scene["tip"] = {"type": "clamped", "position": position,
                            "quaternion": list(q / np.linalg.norm(q))}
    if rng.random() < 0.6 and held < 0.8:
        direction = unit(rng) if rng.random() < 0.7 else np.array([0, 0, -1.0]) + 0.2 * unit(rng)
        scene["tip_force"] = list(10 ** rng.uniform(-0.5, math.log10(50)) * ei / length**2
                                  * direction / np.linalg.norm(direction))
    if rng.random() < 0.5 and held < 0.8:
        scene["tip_moment"] = list(10 ** rng.uniform(-0.5, 1) * ei / length * unit(rng))
    if rng.random() < 0.5:
        rho = rng.uniform(0.1, 2)
        w = 10 ** rng.uniform(-0.5, math.log10(50)) * ei / length**3
        scene["gravity"] = {"linear_density": rho, "vector": list(w / rho * unit(rng))}
    if rng.random() < 0.5:
        scene["rest_curvature"] = [list(rng.uniform(-1, 1, 2) * 10 ** rng.uniform(-0.3, 1)
                                        / length) for _ in range(int(rng.integers(1, 5)))]
    return scene


def shooting(count: int) -> None:
    """Where Newton (the default solve) and shooting both converge, at the same
    n, their answers more than 0.1 L apart, by tip and by stability; and where
    only Newton converges."""
    rng = np.random.default_rng(20240601)
    apart: Counter = Counter()
    both = only_newton = 0
    for _ in range(count):
        scene = shooting_scene(rng)
        try:
            newton = softspine.solve(scene, n_elements=20)
            shot = softspine.solve(scene, n_elements=20, method="shooting")
        except ValueError:
            continue
        tip = scene.get("tip", {}).get("type", "free")
        if newton.converged and shot.converged:
            both += 1
            if np.abs(newton.positions - shot.positions).max() > 0.1 * scene["length"]:
                apart[(tip, f"newton {'stable' if newton.stable else 'unstable'}",
                       f"shooting {'stable' if shot.stable else 'unstable'}")] += 1
        elif newton.converged:
            only_newton += 1
    print(f"{both} scenes both converged; more than 0.1 L apart: {sum(apart.values())}")
    for key, value in sorted(apart.items()):
        print(f"  {value:4d} {key}")
    print(f"{only_newton} where only Newton converged (shooting says it could not)")


def tol(count: int) -> None:
    """Accuracy on demand on scenes whose point load, guide or tendon anchor
    the default n puts on a node."""
    rng = np.random.default_rng(3)
    refused = total = 0
    for _ in range(count):
        s = float(rng.choice([0.05, 0.15, 0.35, 0.45, 0.65, 0.7, 0.85, 0.95]))
        kind = rng.integers(3)
        scene: dict = {"length": 1.0, "stiffness": {"kx": 1.0, "ky": 1.0, "kz": 1.0}}
        if rng.random() < 0.5:
            scene["rest_curvature"] = [[float(rng.uniform(0, 8)), 0.0]]
        if kind == 0:
            scene["point_loads"] = [{"s": s, "force": list(rng.normal(size=3))}]
        elif kind == 1:
            scene["tendons"] = [{"tension": 5.0, "offset": [0.01, 0.0], "end": s}]
        else:
            plain = softspine.solve(scene, n_elements=20)
            node = round(20 * s)
            scene["guides"] = [{"s": s, "position": list(plain.positions[node])}]
        for kwargs in ({"tol": 1e-4}, {"tol": 1e-7}, {"tol": 1e-4, "scheme": "fe4"}):
            total += 1
            try:
                softspine.solve(scene, **kwargs)
            except ValueError as e:
                refused += "must fall on a node" in str(e)
    print(f"{total} solves with tol=: {refused} refused with 'must fall on a node'")


def threads(count: int) -> None:
    """Threads sharing one Solver, each setting its own actuation and solving."""
    robot = softspine.Robot()
    actuations = robot.workspace(40, 0.03, seed=3, progress=False).actuations
    expected = [robot.forward(k, 0.03).tip_position for k in actuations]
    solver = softspine.Solver(robot.scene(actuations[0], 0.03), n_elements=20)
    tally: Counter = Counter()
    lock = threading.Lock()

    def work(t: int) -> None:
        for rep in range(count // 40):
            i = (t * 10 + rep) % 40
            try:
                solver.set_rest_curvature(actuations[i])
                tip = solver.solve().tip_position
                outcome = "right" if np.abs(tip - expected[i]).max() < 1e-6 else "wrong"
            except RuntimeError:
                outcome = "refused"
            with lock:
                tally[outcome] += 1

    workers = [threading.Thread(target=work, args=(t,)) for t in range(40)]
    for w in workers:
        w.start()
    for w in workers:
        w.join()
    print(f"{sum(tally.values())} set_rest_curvature + solve by 40 threads: {dict(tally)}")


def sensitivity_scene(rng: np.random.Generator) -> tuple[dict, list[str]]:
    """A rod in random units (length 1e-2 to 1e3, stiffness 1e-9 to 1e5) with
    dimensionless loads of order one, tendons, magnets or sections of their
    own, and the parameters to differentiate."""
    length, k = 10 ** rng.uniform(-2, 3), 10 ** rng.uniform(-9, 5)
    force, m = k / length**2, int(rng.integers(1, 4))
    scene: dict = {"length": length, "stiffness": {"kx": k, "ky": k * rng.uniform(0.5, 2),
                                                   "kz": 0.7 * k},
                   "rest_curvature": [list(rng.normal(size=2) / length) for _ in range(m)],
                   "gravity": {"linear_density": 0.5 * force / 9.81, "vector": [0, 0, -9.81]},
                   "tip_force": list(rng.normal(size=3) * force),
                   "tip_moment": list(rng.normal(size=3) * 0.3 * k / length)}
    scene["tip_force"][2] = 0.0  # a parameter at zero: its step once came from its units
    names = ["tip_force[0]", "tip_force[2]", "tip_moment[2]", "stiffness.kx",
             "gravity.linear_density", f"rest_curvature[{m - 1}][0]"]
    kind = rng.integers(3)
    if kind == 0:
        scene["tendons"] = [{"tension": float(rng.uniform(0, 1)) * k / (0.02 * length**2),
                             "offset": [0.02 * length, 0.0], "twist": float(rng.normal() / length)}]
        names += ["tendons[0].tension", "tendons[0].offset[0]"]
    elif kind == 1:
        scene["magnetization"] = [[0.0, 0.0, 1.0]]
        scene["magnetic_field"] = list(rng.normal(size=3) * k / length**2)
        names += ["magnetic_field[0]", "magnetic_field[2]"]
    else:
        fractions = rng.uniform(0.5, 1.5, size=m)
        scene["sections"] = [{"length": float(f * length / fractions.sum()),
                              "stiffness": {"kx": k * s, "ky": k * s, "kz": 0.7 * k * s}}
                             for f, s in zip(fractions, rng.uniform(0.5, 2, size=m), strict=True)]
        scene["length"] = sum(p["length"] for p in scene["sections"])
        names += ["sections[0].length", f"sections[{m - 1}].stiffness.kz"]
    return scene, names


def leaf(data: dict, name: str) -> tuple:
    """The container of the scene's field `name` (a path) and its key."""
    parts = re.findall(r"[^.\[\]]+", name)
    box: Any = data
    for part in parts[:-1]:
        box = box[int(part)] if isinstance(box, list) else box[part]
    return box, int(parts[-1]) if isinstance(box, list) else parts[-1]


def tip_moved(scene: dict, name: str, delta: float, initial: softspine.Solution):
    """The converged tip with the field `name` moved by `delta` (a section's
    length moves the rod's), or None."""
    data = copy.deepcopy(scene)
    box, key = leaf(data, name)
    box[key] += delta
    if name.startswith("sections[") and name.endswith(".length"):
        data["length"] += delta
    sol = softspine.solve(data, n_elements=36, residual_tol=1e-13, initial=initial)
    return sol.tip_position if sol.converged else None


def sensitivity(count: int) -> None:
    """Every column of Solver.sensitivity against a five-point difference of
    whole solves (step 1e-3 of the parameter, or of its scale where zero)."""
    rng = np.random.default_rng(3)
    worst, tally = [], Counter()
    for _ in range(count):
        scene, names = sensitivity_scene(rng)
        solver = softspine.Solver(scene, n_elements=36, residual_tol=1e-13)
        base = solver.solve()
        if not (base.converged and base.stable):
            tally["not converged"] += 1
            continue
        try:
            sens = solver.sensitivity(names)
        except ValueError:
            tally["refused"] += 1
            continue
        for j, name in enumerate(names):
            box, key = leaf(solver.scene.to_dict(), name)
            scale = scene["stiffness"]["kx"] / scene["length"] ** 2  # only tip_force[2] is 0
            h = 1e-3 * (abs(float(box[key])) or scale)
            tips = [tip_moved(scene, name, k * h, base) for k in (2, 1, -1, -2)]
            if any(t is None for t in tips):
                tally["difference not converged"] += 1
                continue
            fd = (-tips[0] + 8 * tips[1] - 8 * tips[2] + tips[3]) / (12 * h)
            # Below the whole solves' noise (1e-10 L over the step) a column
            # is zero (a field the sections' own values override).
            size = np.abs(fd).max()
            noise = 1e-10 * scene["length"] / h
            if size < noise and np.abs(sens.tip_position[:, j]).max() < noise:
                continue
            error = np.abs(sens.tip_position[:, j] - fd).max() / max(size, noise)
            tally["columns"] += 1
            tally["off by > 1e-3"] += int(error > 1e-3)
            tally["off by > 1e-6"] += int(error > 1e-6)
            worst.append((error, name, scene["length"], scene["stiffness"]["kx"]))
    print(f"{count} scenes: {dict(tally)}")
    for error, name, length, k in sorted(worst, reverse=True)[:5]:
        print(f"  {error:.1e}  {name}  (L = {length:.3g}, kx = {k:.3g})")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument(
        "campaign", choices=["sections", "shooting", "tol", "threads", "sensitivity"]
    )
    parser.add_argument("--count", type=int, default=None)
    args = parser.parse_args()
    counts = {"sections": 200, "shooting": 2000, "tol": 100, "threads": 400, "sensitivity": 300}
    globals()[args.campaign](args.count or counts[args.campaign])


if __name__ == "__main__":
    main()
