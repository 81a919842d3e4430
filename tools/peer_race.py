"""The default call against ContinuumRobotExamples' shooting, the public peer.

``python tools/peer_race.py [--examples DIR]`` builds the two C++ harnesses
of ``tools/peer`` (g++ -O3 -march=native; Eigen from ``--eigen``, by default
Debian's ``/usr/include/eigen3``, or the copy inside a ContinuumRobotExamples
checkout given with ``--examples``): ``tuned.cpp``, the peer's algorithm (RK4
shooting, Levenberg-Marquardt with a forward-difference Jacobian, from a zero
guess) with fixed-size types and no allocation, and, with ``--examples``,
``teaching.cpp``, the peer's own ``ode4`` and ``solveLevenbergMarquardt`` as
published. Each solves the cantilevers alpha = 3 and 10 at 4 to 128 elements
(sum of squares to 1e-20: the published 1e-12 leaves 1e-6 of the tip
moment), the median of 2,000 (tuned) or 400 (teaching) solves, pinned to
core 1; softspine runs pinned to core 0, from Python (its call included),
``tol=level`` and its fastest fixed shooting setting, best of 7 rounds of
40 ms. At each level 1e-3 to 1e-8 L every method takes its fastest n whose
every node is within the level of fe4 at n = 2560.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

import softspine

sys.path.insert(0, str(Path(__file__).resolve().parent))
from race import best_time, nodes_error  # noqa: E402

HERE = Path(__file__).resolve().parent / "peer"
LEVELS = (1e-3, 1e-4, 1e-5, 1e-6, 1e-8)
SHOOTING_GRID = (4, 5, 8, 10, 16, 20, 32, 40, 64, 80, 128)


def build(source: str, includes: list[str], out: Path) -> Path:
    subprocess.run(["g++", "-O3", "-march=native", "-DNDEBUG", *[f"-I{i}" for i in includes],
                    str(HERE / source), "-o", str(out)], check=True)
    return out


def peer_runs(exe: Path, alpha: float, ref: softspine.Solution) -> list[tuple[int, float, float]]:
    """(elements, median time [us], largest node error [m]) per converged size."""
    out = subprocess.run(["taskset", "-c", "1", str(exe), str(alpha), "1e-20"],
                         capture_output=True, text=True, check=True).stdout
    runs = []
    for line in out.splitlines():
        v = line.split()
        if len(v) < 3 or not v[0].isdigit():
            continue  # a size it did not solve, or its own diagnostics
        points = int(v[0])
        nodes = np.array(v[2:], dtype=float).reshape(-1, 3)
        error = np.linalg.norm(nodes - ref.positions_at(np.linspace(0.0, 1.0, points)), axis=1)
        runs.append((points - 1, float(v[1]), float(error.max())))
    return runs


def fastest(runs: list[tuple[int, float, float]], level: float) -> tuple[float, int | None]:
    met = [(t, n) for n, t, e in runs if e <= level]
    return min(met) if met else (float("nan"), None)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--examples", help="a ContinuumRobotExamples checkout (for teaching.cpp)")
    parser.add_argument("--eigen", default="/usr/include/eigen3", help="Eigen's include folder")
    args = parser.parse_args()
    os.sched_setaffinity(0, {0})
    with tempfile.TemporaryDirectory() as tmp:
        eigen = args.eigen
        if args.examples:
            eigen = str(Path(args.examples) / "Library" / "eigen")
        peers = {"tuned": build("tuned.cpp", [eigen], Path(tmp) / "tuned")}
        if args.examples:
            library = str(Path(args.examples) / "Library")
            peers["teaching"] = build("teaching.cpp", [library, eigen], Path(tmp) / "teaching")
        ratios: dict[str, list[float]] = {name: [] for name in peers}
        for alpha in (3.0, 10.0):
            scene = {"length": 1.0, "stiffness": {"kx": 1.0, "ky": 1.0, "kz": 1.0},
                     "tip_force": [0.0, -alpha, 0.0]}
            ref = softspine.solve(scene, scheme="fe4", n_elements=2560, residual_tol=1e-13)
            runs = {name: peer_runs(exe, alpha, ref) for name, exe in peers.items()}
            for level in LEVELS:
                sol = softspine.solve(scene, tol=level)
                ours = best_time(lambda s=scene, t=level: softspine.solve(s, tol=t))
                shot = next(n for n in SHOOTING_GRID if nodes_error(
                    softspine.solve(scene, n_elements=n, method="shooting"), ref) <= level)
                shot_time = best_time(
                    lambda s=scene, n=shot: softspine.solve(s, n_elements=n, method="shooting"))
                line = [f"alpha={alpha:g} {level:.0e}: tol= {ours:.0f} us (n={sol.n_elements}), "
                        f"shooting {shot_time:.0f} us (n={shot})"]
                for name in peers:
                    t, n = fastest(runs[name], level)
                    ratios[name].append(t / ours)
                    line.append(f"{name} {t:.0f} us (n={n}): {t / ours:.1f} x tol=, "
                                f"{t / shot_time:.1f} x shooting")
                print(" | ".join(line), flush=True)
        for name, r in ratios.items():
            r = [x for x in r if np.isfinite(x)]
            print(f"{name} / tol=: geometric mean {np.exp(np.mean(np.log(r))):.1f}, "
                  f"{min(r):.1f} to {max(r):.1f}")


if __name__ == "__main__":
    main()
