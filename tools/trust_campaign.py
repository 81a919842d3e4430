"""Counts of the trust campaign (issue 25), seeded, to rerun on any build.

    python tools/trust_campaign.py sections   # tight residual_tol, sections of own stiffness
    python tools/trust_campaign.py shooting   # shooting against Newton on random scenes
    python tools/trust_campaign.py tol        # accuracy on demand with located inputs
    python tools/trust_campaign.py threads    # one Solver shared by threads (set_* then solve)

Each prints what it counted; the regression tests keep the reproducers.
"""

from __future__ import annotations

import argparse
import math
import threading
from collections import Counter

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


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("campaign", choices=["sections", "shooting", "tol", "threads"])
    parser.add_argument("--count", type=int, default=None)
    args = parser.parse_args()
    counts = {"sections": 200, "shooting": 2000, "tol": 100, "threads": 400}
    globals()[args.campaign](args.count or counts[args.campaign])


if __name__ == "__main__":
    main()
