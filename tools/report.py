"""Speed against error: every method and scheme on a fixed suite of scenes.

``python tools/report.py [--out docs] [--readme docs/reference.md]`` solves each scene
with Newton on both schemes (``fd2``, ``fe4``), ``shooting``, ``lm``, ``paper``
(when the build has it) and the NumPy reference at n = 5 ... 160, and with
accuracy on demand at tol = 1e-3 ... 1e-6. It measures the median wall time of
a solve (Python call included), the tip error and the whole backbone's error
(the largest over the nodes) against a shooting solution of the continuous
rod (rtol 1e-12), and writes ``report.md`` (a Markdown table) and
``report.png`` (log-log whole-backbone error against time, one curve per method
and scene).
"""

from __future__ import annotations

import argparse
import math
import time
from pathlib import Path

import numpy as np

from softspine import solve
from softspine.scenes import cantilever, end_moment

from validation import reference, shooting

NS = (5, 10, 20, 40, 80, 160)
# The reference is sampled at s = i L / SAMPLES: every n of NS divides it.
SAMPLES = 640
TOLS = (1e-3, 1e-4, 1e-5, 1e-6)
REFERENCE_MAX_N = 40  # the NumPy reference is slow: dense complex-step Jacobians


def suite() -> dict[str, dict]:
    """The scenes of the report, hard cases included."""
    robot = {
        "length": 1.0,
        "stiffness": {"E": 200e9, "G": 77e9, "diameter": 0.003},
        "rest_curvature": [[3 * math.cos(0.6 * k), 3 * math.sin(0.6 * k)] for k in range(5)],
        "gravity": {"linear_density": 0.2, "vector": [0.0, 0.0, -9.81]},
        "tip_force": [0.0, 0.0, -0.2943],
        "base_quaternion": [0.0, 1.0, 0.0, 0.0],
    }
    spiral = {
        "length": 1.0,
        "stiffness": {"kx": 1.0, "ky": 1.0, "kz": 0.7},
        "rest_curvature": [[8.0 * math.cos(k), 8.0 * math.sin(k)] for k in range(5)],
        "gravity": {"linear_density": 0.1, "vector": [0.0, 0.0, -9.81]},
    }
    return {
        "cantilever alpha=3": cantilever(3.0),
        "cantilever alpha=10": cantilever(10.0),
        "full roll-up 2 pi EI/L": end_moment(1.0),
        "3D robot, 5 sections, gravity + 30 g": robot,
        "3D spiral, rest turning 8 rad, gravity": spiral,
    }


def available_methods() -> dict[str, dict]:
    """The solve keywords of each curve, by its label."""
    methods = {
        "newton fd2": {"method": "newton", "scheme": "fd2"},
        "newton fe4": {"method": "newton", "scheme": "fe4"},
        "shooting": {"method": "shooting"},
        "lm": {"method": "lm"},
    }
    try:
        solve(cantilever(1.0), n_elements=4, method="paper")
        methods["paper"] = {"method": "paper"}
    except ValueError:
        pass
    return methods


def backbone_error(positions: np.ndarray, exact: np.ndarray) -> float:
    """Largest distance of a node from the continuous rod, at the nodes the
    solution and the reference samples share."""
    n = len(positions) - 1
    if SAMPLES % n == 0:
        return float(np.abs(positions - exact[:: SAMPLES // n]).max())
    if n % SAMPLES == 0:
        return float(np.abs(positions[:: n // SAMPLES] - exact).max())
    return float("nan")


def timed(fn, repeats: int):
    times = []
    result = None
    for _ in range(repeats):
        t0 = time.perf_counter()
        result = fn()
        times.append(time.perf_counter() - t0)
    return result, float(np.median(times))


def run(out: Path, quick: bool = False) -> list[dict]:
    rows = []
    methods = available_methods()
    for name, scene in suite().items():
        ref = shooting.solve(scene, rtol=1e-12, n_samples=SAMPLES + 1)
        exact, exact_tip = ref["positions"], ref["tip_position"]
        length = scene["length"]
        sections = len(scene.get("rest_curvature", [[0, 0]]))

        def add(method, setting, t, tip, positions, ok, name=name, length=length,
                exact=exact, exact_tip=exact_tip):
            rows.append({"scene": name, "method": method, "setting": setting, "time": t,
                         "error": np.linalg.norm(tip - exact_tip) / length,
                         "shape": backbone_error(positions, exact) / length,
                         "converged": ok})

        for label in [*methods, "reference"]:
            for n in NS:
                if n % sections or (label == "reference" and n > REFERENCE_MAX_N):
                    continue
                if label == "paper" and n > 40:
                    continue
                repeats = 1 if label in ("reference", "paper") or quick else 7
                if label == "reference":
                    try:
                        res, t = timed(
                            lambda n=n, s=scene: reference.solve(s, n_elements=n), repeats
                        )
                    except RuntimeError:  # its own continuation gave up (coarse n)
                        continue
                    add(label, f"n={n}", t, res["tip_position"], res["positions"], True)
                else:
                    sol, t = timed(
                        lambda k=methods[label], n=n, s=scene: solve(s, n_elements=n, **k),
                        repeats,
                    )
                    add(label, f"n={n}", t, sol.tip_position, sol.positions, sol.converged)
        for tol in TOLS:
            for refine in (None, "richardson"):
                sol, t = timed(
                    lambda tol=tol, refine=refine, s=scene: solve(s, tol=tol, refine=refine),
                    1 if quick else 5,
                )
                # The method and scheme are the default's choice (method
                # "auto") for the tolerance: the setting names them.
                label = "default, tol" + (" + Richardson" if refine else "")
                add(label, f"tol={tol:g} ({sol.scheme}, n={sol.n_elements})", t, sol.tip_position,
                    sol.positions, sol.converged)
    write_table(rows, out / "report.md")
    write_plot(rows, out / "report.png")
    return rows


def write_table(rows: list[dict], path: Path) -> None:
    lines = ["| scene | method | setting | median time | tip error / L "
             "| backbone error / L | converged |",
             "|---|---|---|---:|---:|---:|---|"]
    for r in rows:
        lines.append(f"| {r['scene']} | {r['method']} | {r['setting']} | "
                     f"{format_time(r['time'])} | {r['error']:.1e} | {r['shape']:.1e} | "
                     f"{'yes' if r['converged'] else 'no'} |")
    path.write_text("\n".join(lines) + "\n")


def format_time(t: float) -> str:
    if t < 1e-3:
        return f"{t * 1e6:.0f} us"
    if t < 1.0:
        return f"{t * 1e3:.1f} ms"
    return f"{t:.2f} s"


def write_plot(rows: list[dict], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    scenes = list(dict.fromkeys(r["scene"] for r in rows))
    methods = list(dict.fromkeys(r["method"] for r in rows))
    fig, axes = plt.subplots(2, 3, figsize=(15, 9), sharex=True, sharey=True)
    for ax, scene in zip(axes.flat, scenes, strict=False):
        for method in methods:
            pts = [(r["time"], max(r["shape"], 1e-12)) for r in rows
                   if r["scene"] == scene and r["method"] == method and r["converged"]
                   and math.isfinite(r["shape"])]
            if pts:
                t, e = zip(*sorted(pts), strict=True)
                ax.loglog(t, e, "o-", ms=4, label=method)
        ax.set_title(scene, fontsize=10)
        ax.grid(True, which="both", alpha=0.3)
    for ax in axes[-1]:
        ax.set_xlabel("median time per solve [s] (Python call included)")
    for ax in axes[:, 0]:
        ax.set_ylabel("whole-backbone error / L")
    axes.flat[0].legend(fontsize=8)
    for ax in axes.flat[len(scenes):]:
        ax.set_visible(False)
    fig.suptitle("softspine: whole-backbone error against time (each point one n or tol)")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


START, END = "<!-- report-table -->", "<!-- /report-table -->"


def update_readme(readme: Path, table: str) -> bool:
    """Put the table between the report markers of the README, if it has them."""
    if not readme.exists():
        return False
    text = readme.read_text()
    if START not in text or END not in text:
        return False
    head, rest = text.split(START, 1)
    _, tail = rest.split(END, 1)
    block = f"{START}\n<details><summary>The whole table</summary>\n\n{table}\n</details>\n"
    readme.write_text(head + block + END + tail)
    return True


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="tools/report.py", description=__doc__)
    parser.add_argument("--out", default="docs", help="folder for report.md and report.png")
    parser.add_argument("--readme", default=None,
                        help="also put the table in this README (between its report markers)")
    parser.add_argument("--quick", action="store_true", help="one repetition per timing")
    args = parser.parse_args(argv)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    rows = run(out, quick=args.quick)
    print(f"{len(rows)} rows written to {out / 'report.md'}, plot {out / 'report.png'}")
    if args.readme is None:
        return 0
    if not update_readme(Path(args.readme), (out / "report.md").read_text()):
        print(f"{args.readme}: no report markers ({START} ... {END}), not updated")
        return 1
    print(f"table updated in {args.readme}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
