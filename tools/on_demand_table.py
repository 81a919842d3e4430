"""The accuracy-on-demand table of docs/reference.md ("Accuracy on demand").

``python tools/on_demand_table.py`` solves the report's scenes
(``tools/report.py``'s suite) with ``tol=`` and, where the row asks, a
scheme; prints one Markdown row each: the scheme used, n, the error
estimate and the tip's true error (both over L, the truth a shooting
solution of the continuous rod at rtol 1e-13) and the median of 5 calls
from Python.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))

import softspine  # noqa: E402

from report import suite  # noqa: E402
from validation import shooting  # noqa: E402

ROBOT = "3D robot, 5 sections, gravity + 30 g"
SPIRAL = "3D spiral, rest turning 8 rad, gravity"
ROWS = [("cantilever alpha=10", 1e-4, None), ("cantilever alpha=10", 1e-6, "fd2"),
        ("cantilever alpha=10", 1e-6, None), ("cantilever alpha=10", 1e-8, "fd2"),
        ("cantilever alpha=10", 1e-8, None), (ROBOT, 1e-6, "fd2"), (ROBOT, 1e-6, None),
        (SPIRAL, 1e-6, "fd2"), (SPIRAL, 1e-6, None),
        ("full roll-up 2 pi EI/L", 1e-8, "fd2"), ("full roll-up 2 pi EI/L", 1e-8, None)]
SHORT = {ROBOT: "3D robot, 5 sections, 30 g", SPIRAL: "3D spiral, 8 rad, gravity"}


def main() -> None:
    scenes = suite()
    truth: dict[str, np.ndarray] = {}
    for name, tol, scheme in ROWS:
        scene = scenes[name]
        if name not in truth:
            truth[name] = shooting.solve(scene, rtol=1e-13)["tip_position"]
        kwargs: dict = {"tol": tol}
        if scheme:
            kwargs["scheme"] = scheme
        times = []
        for _ in range(5):
            t0 = time.perf_counter()
            sol = softspine.solve(scene, **kwargs)
            times.append(time.perf_counter() - t0)
        length = scene["length"]
        label = f"{scheme} (asked)" if scheme else f"{sol.scheme} (default)"
        status = "" if sol.converged else f", {sol.status}"
        t = float(np.median(times))
        shown = f"{t * 1e3:.2f} ms" if t < 0.1 else f"{t * 1e3:.0f} ms"
        error = np.linalg.norm(sol.tip_position - truth[name]) / length
        print(f"| {SHORT.get(name, name)} | {tol:g} | {label} | {sol.n_elements} "
              f"| {sol.error_estimate / length:.1e} | {error:.1e} | {shown}{status} |")


if __name__ == "__main__":
    main()
