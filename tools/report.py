"""Speed against error: every method on a fixed suite of scenes.

``python tools/report.py [--out docs] [--readme README.md]`` solves each scene with ``newton``,
``lm``, ``paper`` (when the build has it) and the NumPy reference at
n = 5 ... 160, and with accuracy on demand at tol = 1e-3 ... 1e-6; it measures
the median wall time of a solve (Python call included) and the tip error
against a shooting solution of the continuous rod (rtol 1e-12), and writes
``report.md`` (a Markdown table) and ``report.png`` (log-log error against time,
one curve per method and scene).
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
        "full roll-up 2 pi EI/L": end_moment(1.0),
        "3D robot, 5 sections, gravity + 30 g": robot,
        "3D spiral, rest turning 8 rad, gravity": spiral,
    }


def available_methods() -> list[str]:
    methods = ["newton", "lm"]
    try:
        solve(cantilever(1.0), n_elements=4, method="paper")
        methods.append("paper")
    except ValueError:
        pass
    return methods


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
        exact = shooting.solve(scene, rtol=1e-12)["tip_position"]
        length = scene["length"]
        sections = len(scene.get("rest_curvature", [[0, 0]]))
        for method in methods + ["reference"]:
            for n in NS:
                if n % sections or (method == "reference" and n > REFERENCE_MAX_N):
                    continue
                if method == "paper" and n > 40:
                    continue
                repeats = 1 if method in ("reference", "paper") or quick else 7
                if method == "reference":
                    try:
                        res, t = timed(
                            lambda n=n, s=scene: reference.solve(s, n_elements=n), repeats
                        )
                    except RuntimeError:  # its own continuation gave up (coarse n)
                        continue
                    tip, ok = res["tip_position"], True
                else:
                    sol, t = timed(
                        lambda m=method, n=n, s=scene: solve(s, n_elements=n, method=m), repeats
                    )
                    tip, ok = sol.tip_position, sol.converged
                rows.append({"scene": name, "method": method, "setting": f"n={n}",
                             "time": t, "error": np.linalg.norm(tip - exact) / length,
                             "converged": ok})
        for tol in TOLS:
            for refine in (None, "richardson"):
                sol, t = timed(
                    lambda tol=tol, refine=refine, s=scene: solve(s, tol=tol, refine=refine),
                    1 if quick else 5,
                )
                label = "newton, tol" + (" + Richardson" if refine else "")
                rows.append({"scene": name, "method": label,
                             "setting": f"tol={tol:g} (n={sol.n_elements})", "time": t,
                             "error": np.linalg.norm(sol.tip_position - exact) / length,
                             "converged": sol.converged})
    write_table(rows, out / "report.md")
    write_plot(rows, out / "report.png")
    return rows


def write_table(rows: list[dict], path: Path) -> None:
    lines = ["| scene | method | setting | median time | tip error / L | converged |",
             "|---|---|---|---:|---:|---|"]
    for r in rows:
        lines.append(f"| {r['scene']} | {r['method']} | {r['setting']} | "
                     f"{format_time(r['time'])} | {r['error']:.1e} | "
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
    fig, axes = plt.subplots(2, 2, figsize=(11, 9), sharex=True, sharey=True)
    for ax, scene in zip(axes.flat, scenes, strict=False):
        for method in methods:
            pts = [(r["time"], max(r["error"], 1e-12)) for r in rows
                   if r["scene"] == scene and r["method"] == method and r["converged"]]
            if pts:
                t, e = zip(*sorted(pts), strict=True)
                ax.loglog(t, e, "o-", ms=4, label=method)
        ax.set_title(scene, fontsize=10)
        ax.grid(True, which="both", alpha=0.3)
    for ax in axes[-1]:
        ax.set_xlabel("median time per solve [s] (Python call included)")
    for ax in axes[:, 0]:
        ax.set_ylabel("tip error / L")
    axes.flat[0].legend(fontsize=8)
    fig.suptitle("softspine: tip error against time (each point one n or tol)")
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
