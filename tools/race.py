"""Time to accuracy of the default call against every method's best setting.

``python tools/race.py`` solves issue 30's race scenes (cantilevers alpha = 3
and 10, a precurved 10-section rod under gravity) with ``tol=level`` (the
default settings: the core chooses the method, scheme and n) at levels 1e-3
to 1e-8 L, and with each fixed setting (Newton on fd2, on fe4, shooting) at
the smallest n of a grid whose every node is within the level of a
fourth-order reference (fe4, n = 2560). Times are the best of 7 rounds of
40 ms of calls from Python. It prints one line a scene and level, the ratio
of the default's time to the fastest setting's, and their geometric mean,
and the default's own error at the backbone's nodes against the reference.
``--method newton`` races ``tol=level, method="newton"`` instead: the
choice the default made before it could pick shooting.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

import softspine

LEVELS = (1e-3, 1e-4, 1e-5, 1e-6, 1e-8)
GRIDS = {
    "fd2": ({"scheme": "fd2", "method": "newton"}, [10, 20, 40, 80, 160, 320, 640, 1280, 2560]),
    "fe4": ({"scheme": "fe4"}, [4, 5, 8, 10, 16, 20, 32, 40, 64, 80, 128, 160]),
    "shooting": ({"method": "shooting"}, [4, 5, 8, 10, 16, 20, 32, 40, 64, 80, 128, 160]),
}


def cantilever(alpha: float) -> dict:
    return {"length": 1.0, "stiffness": {"kx": 1.0, "ky": 1.0, "kz": 1.0},
            "tip_force": [0.0, -alpha, 0.0]}


def precurved() -> dict:
    curvature = [[3.0 * np.cos(i), 3.0 * np.sin(i)] for i in range(10)]
    return {"length": 1.0, "stiffness": {"kx": 1.0, "ky": 1.0, "kz": 0.7},
            "rest_curvature": curvature,
            "gravity": {"linear_density": 0.3, "vector": [0, 0, -9.81]}}


def best_time(call) -> float:
    """The best of 7 rounds of 40 ms of calls [us]."""
    call()
    best = float("inf")
    for _ in range(7):
        t0, k = time.perf_counter(), 0
        while time.perf_counter() - t0 < 0.04:
            call()
            k += 1
        best = min(best, (time.perf_counter() - t0) / k * 1e6)
    return best


def nodes_error(sol: softspine.Solution, ref: softspine.Solution) -> float:
    """Largest distance of a node from the reference at its arc length [m]
    (between the reference's nodes at its scheme's order, fourth)."""
    at = ref.positions_at(sol.arc_length)
    return float(np.linalg.norm(sol.positions - at, axis=1).max())


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--method", default="auto", help="the method of the tol= call")
    method = parser.parse_args().method
    scenes = {"cantilever alpha=3": cantilever(3.0), "cantilever alpha=10": cantilever(10.0),
              "precurved 10 sections, gravity": precurved()}
    ratios, missed = [], []
    for name, scene in scenes.items():
        ref = softspine.solve(scene, scheme="fe4", n_elements=2560, residual_tol=1e-13)
        sections = len(scene.get("rest_curvature", [[0, 0]]))
        for level in LEVELS:
            sol = softspine.solve(scene, tol=level, method=method)
            default = best_time(
                lambda s=scene, t=level: softspine.solve(s, tol=t, method=method))
            best = {}
            for label, (kwargs, grid) in GRIDS.items():
                for n in (n for n in grid if n % sections == 0):
                    trial = softspine.solve(scene, n_elements=n, **kwargs)
                    if nodes_error(trial, ref) <= level * scene["length"]:
                        timed = best_time(
                            lambda s=scene, n=n, k=kwargs: softspine.solve(s, n_elements=n, **k))
                        best[label] = (timed, n)
                        break
            fastest = min(t for t, _ in best.values())
            ratios.append(default / fastest)
            settings = " ".join(f"{k} {t:.0f} us (n={n})" for k, (t, n) in best.items())
            # The default's own error against the reference: the tolerance is
            # only worth its time if it is met.
            error = nodes_error(sol, ref) / scene["length"]
            missed.append(error > level)
            print(f"{name} {level:.0e}: default {default:.0f} us ({sol.scheme}, "
                  f"n={sol.n_elements}, error {error:.1e} L{' MISSED' if error > level else ''}) "
                  f"| {settings} | ratio {default / fastest:.2f}", flush=True)
    print(f"geometric mean of the ratios {np.exp(np.mean(np.log(ratios))):.2f}, "
          f"largest {max(ratios):.2f}; the default missed its level at {sum(missed)} "
          f"of {len(missed)} points")


if __name__ == "__main__":
    main()
