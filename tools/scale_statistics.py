"""Scale statistics (issue 10, item 11): do scenes that converge at a base n
converge at 8, 32 and 128 times that n, with an iteration count that does not
grow with n? And does accuracy on demand (``tol=1e-6``) deliver?

Random valid scenes: anisotropic stiffness (ky/kx in [0.2, 5], kz/kx up to 300),
1 to 4 sections of rest curvature up to |kappa L| = 6, gravity in a random
direction, a tip force and a tip moment, a random base orientation on some, and a
pinned tip on about a quarter (the free solution's tip moved inward by 3 to 20 %
of its distance from the base: a reachable point).

Every scene is solved at the base n; those that converge are solved again at
``factor * base_n`` for each factor and with ``tol=1e-6``. Per scene and per n
the record holds: converged, status, message, iterations, continuation steps,
residual, stable, energy, wall time, the tip's distance to the base-n tip and
the largest distance at the base nodes to the base-n solve and to the previous
factor's (over L; a pinned tip never moves, so the tip alone cannot tell two
equilibria apart). The summary flags converged solves that look like another
equilibrium than at the previous n, and lists iteration growth beyond +3.
The ``tol`` solve is compared with a Richardson estimate from the two finest
fixed-n solves (tip) and with the finest one (every node, interpolated).

    python tools/scale_statistics.py                       # 599 scenes, 8 32 128
    python tools/scale_statistics.py --scenes 50 --factors 8 --out run.json
    python tools/scale_statistics.py --only 97 324 --tol 0 --failures -   # reproduce

Failing scenes (converged at the base n, not at a finer n or with ``tol``) are
written to ``--failures`` (default tools/scale_failures.json) as reproducers.
Single process; the solves run one after another.
"""

from __future__ import annotations

import argparse
import json
import math
import platform
import subprocess
import sys
import time
from collections import Counter
from pathlib import Path

import numpy as np

import softspine

HERE = Path(__file__).resolve().parent


# --- scenes ------------------------------------------------------------------------


def unit_vector(rng):
    v = rng.normal(size=3)
    return v / np.linalg.norm(v)


def log_uniform(rng, low, high):
    return float(math.exp(rng.uniform(math.log(low), math.log(high))))


def free_scene(rng):
    """A random valid free-tip scene (plain floats, JSON-ready)."""
    length = float(rng.uniform(0.3, 2.0))
    kx = float(rng.uniform(0.2, 2.0))
    ky = kx * log_uniform(rng, 0.2, 5.0)
    kz = kx * log_uniform(rng, 0.3, 300.0)
    ei = min(kx, ky)
    sections = int(rng.integers(1, 5))
    curvature = []
    for _ in range(sections):
        magnitude = rng.uniform(0.0, 6.0) / length  # |kappa L| <= 6
        angle = rng.uniform(0.0, 2 * math.pi)
        curvature.append([magnitude * math.cos(angle), magnitude * math.sin(angle)])
    # Load parameters: w L^3 / EI in [0, 10], |P| L^2 / EI in [0, 8], |M| L / EI in [0, 4].
    weight = rng.uniform(0.0, 10.0) * ei / length**3
    scene = {
        "length": length,
        "stiffness": {"kx": kx, "ky": ky, "kz": kz},
        "rest_curvature": curvature,
        "gravity": {
            "linear_density": float(weight / 9.81),
            "vector": (9.81 * unit_vector(rng)).tolist(),
        },
        "tip_force": (rng.uniform(0.0, 8.0) * ei / length**2 * unit_vector(rng)).tolist(),
        "tip_moment": (rng.uniform(0.0, 4.0) * ei / length * unit_vector(rng)).tolist(),
    }
    if rng.uniform() < 0.25:
        q = rng.normal(size=4)
        scene["base_quaternion"] = (q / np.linalg.norm(q)).tolist()
    return scene


def make_scene(seed, index, base_n):
    """Scene ``index`` of the run: reproducible from (seed, index) alone."""
    rng = np.random.default_rng([seed, index])
    scene = free_scene(rng)
    pin = rng.uniform() < 0.25
    inward = float(rng.uniform(0.03, 0.2))
    if pin:
        free = softspine.solve(scene, n_elements=base_n)
        if free.converged:
            target = (1.0 - inward) * np.asarray(free.tip_position)
            scene["tip"] = {"type": "pinned", "position": target.tolist()}
    return scene


def tip_kind(scene):
    return scene.get("tip", {"type": "free"})["type"]


# --- solves -------------------------------------------------------------------------


def run_solve(scene, **kwargs):
    start = time.perf_counter()
    try:
        sol = softspine.solve(scene, **kwargs)
    except Exception as exc:  # a refusal is a result too; record it
        return None, {
            "converged": False,
            "status": f"exception:{type(exc).__name__}",
            "message": str(exc),
            "iterations": None,
            "continuation_steps": None,
            "wall_s": time.perf_counter() - start,
        }
    wall = time.perf_counter() - start
    return sol, {
        "n": sol.n_elements,
        "converged": bool(sol.converged),
        "status": sol.status,
        "message": sol.message,
        "iterations": int(sol.iterations),
        "continuation_steps": int(sol.continuation_steps),
        "residual_norm": float(sol.residual_norm),
        "stable": bool(sol.stable),
        "energy": float(sol.energy),
        "wall_s": wall,
        "tip": np.asarray(sol.tip_position).tolist(),
    }


def interpolate_backbone(positions, length, s):
    """Positions of a polyline with equal segments at arc lengths ``s``."""
    n = len(positions) - 1
    grid = np.linspace(0.0, length, n + 1)
    return np.column_stack([np.interp(s, grid, positions[:, k]) for k in range(3)])


def study_scene(index, scene, base_n, factors, tol):
    length = scene["length"]
    record = {"index": index, "tip_type": tip_kind(scene), "scene": scene}
    base_sol, base = run_solve(scene, n_elements=base_n)
    record["base"] = base
    record["fine"] = {}
    if not base["converged"]:
        return record
    base_tip = np.asarray(base_sol.tip_position)
    base_pos = np.asarray(base_sol.positions)
    fine_sols = {}
    previous, previous_f = base_pos, 1
    for f in factors:
        sol, rec = run_solve(scene, n_elements=f * base_n)
        if sol is not None:
            pos = np.asarray(sol.positions)
            rec["tip_diff_to_base"] = float(np.linalg.norm(sol.tip_position - base_tip) / length)
            # The base nodes are nodes of every finer solve (a pinned tip never moves).
            rec["node_diff_to_base"] = float(np.abs(pos[::f] - base_pos).max() / length)
            if sol.converged:
                fine_sols[f] = sol
                if previous is not None and f % previous_f == 0:
                    # Second order: this shrinks like (previous f / f)^2 on one branch.
                    rec["node_diff_to_previous"] = float(
                        np.abs(pos[:: f // previous_f] - previous).max() / length
                    )
                previous, previous_f = pos, f
            else:
                previous = None
        record["fine"][str(f)] = rec
    # The finest converged pair gives a Richardson estimate of the continuous rod.
    exact_tip, finest = None, None
    done = sorted(fine_sols)
    if len(done) >= 2:
        a, b = fine_sols[done[-2]], fine_sols[done[-1]]
        ratio2 = (done[-1] / done[-2]) ** 2
        exact_tip = b.tip_position + (b.tip_position - a.tip_position) / (ratio2 - 1)
        finest = b
    if tol is not None:
        sol, rec = run_solve(scene, tol=tol)
        if sol is not None:
            rec["error_estimate"] = sol.error_estimate
            if exact_tip is not None and sol.converged:
                rec["tip_error"] = float(np.linalg.norm(sol.tip_position - exact_tip) / length)
                s = np.linspace(0.0, length, sol.n_elements + 1)
                ref = interpolate_backbone(np.asarray(finest.positions), length, s)
                rec["backbone_error_vs_finest"] = float(
                    np.abs(np.asarray(sol.positions) - ref).max() / length
                )
        record["tol"] = rec
    return record


# --- summary ------------------------------------------------------------------------


def pct(values, q):
    return float(np.percentile(values, q)) if values else float("nan")


def iteration_stats(values):
    if not values:
        return "-"
    return f"{np.median(values):.0f} / {pct(values, 90):.0f} / {max(values)}"


def med_max(values, fmt):
    if not values:
        return "-"
    return f"{np.median(values):{fmt}} / {max(values):{fmt}}"


def summarize(records, base_n, factors, tol):
    lines = []
    total = len(records)
    base_ok = [r for r in records if r["base"]["converged"]]
    kinds = Counter(r["tip_type"] for r in records)
    base_status = Counter(r["base"]["status"] for r in records)
    lines.append(
        f"scenes: {total} ({', '.join(f'{k} {v}' for k, v in sorted(kinds.items()))}); "
        f"converged at base n = {base_n}: {len(base_ok)} / {total}; "
        f"base statuses: {dict(base_status)}"
    )
    for kind in sorted(kinds):
        sub = [r for r in records if r["tip_type"] == kind]
        ok = sum(r["base"]["converged"] for r in sub)
        lines.append(f"  {kind}: converged at base n {ok} / {len(sub)}")
    lines.append("")
    header = (
        "| factor | n | converged / attempted | failures by status | iterations at base n "
        "(med / p90 / max) | iterations at factor n (med / p90 / max) | ratio fine/base "
        f"(med / max) | fine > base + {FINE_NEWTON} | continuation at fine n "
        "| max node diff to base / L (med / max) | wall at fine n (median / max / total) |"
    )
    lines.append(header)
    lines.append("|" + "---|" * 11)
    for f in factors:
        key = str(f)
        attempted = [r for r in base_ok if key in r["fine"]]
        ok = [r for r in attempted if r["fine"][key]["converged"]]
        failures = Counter(r["fine"][key]["status"] for r in attempted if r not in ok)
        base_it = [r["base"]["iterations"] for r in attempted]
        fine_it = [r["fine"][key]["iterations"] for r in ok]
        ratios = [
            r["fine"][key]["iterations"] / max(r["base"]["iterations"], 1) for r in ok
        ]
        grown = sum(
            r["fine"][key]["iterations"] > r["base"]["iterations"] + FINE_NEWTON for r in ok
        )
        cont = sum(r["fine"][key]["continuation_steps"] > 0 for r in ok)
        diffs = [r["fine"][key]["node_diff_to_base"] for r in ok]
        walls = [r["fine"][key]["wall_s"] for r in attempted]
        lines.append(
            f"| {f} | {f * base_n} | {len(ok)} / {len(attempted)} | "
            f"{dict(failures) if failures else '-'} | {iteration_stats(base_it)} | "
            f"{iteration_stats(fine_it)} | "
            f"{med_max(ratios, '.2f')} | {grown} | {cont} | {med_max(diffs, '.1e')} | "
            f"{np.median(walls) * 1e3:.1f} ms / {max(walls) * 1e3:.0f} ms / {sum(walls):.1f} s |"
        )
    lines.append("")
    # The same by tip type.
    for kind in sorted(kinds):
        for f in factors:
            key = str(f)
            att = [r for r in base_ok if r["tip_type"] == kind and key in r["fine"]]
            ok = [r for r in att if r["fine"][key]["converged"]]
            if not att:
                continue
            fine_it = [r["fine"][key]["iterations"] for r in ok]
            base_it = [r["base"]["iterations"] for r in att]
            ratios = [
                r["fine"][key]["iterations"] / max(r["base"]["iterations"], 1) for r in ok
            ]
            lines.append(
                f"  {kind:6s} x{f:<4d}: {len(ok)} / {len(att)} converged; iterations base "
                f"{iteration_stats(base_it)}, fine {iteration_stats(fine_it)}; ratio "
                f"{med_max(ratios, '.2f')}"
            )
    if tol is not None:
        lines.append("")
        everything = [r for r in records if "tol" in r]
        ok = [r for r in everything if r["tol"]["converged"]]
        statuses = Counter(r["tol"]["status"] for r in everything if not r["tol"]["converged"])
        lines.append(
            f"tol={tol:g} (scenes converged at base n): {len(ok)} / {len(everything)} converged; "
            f"failures by status: {dict(statuses) if statuses else '-'}"
        )
        if ok:
            ns = [r["tol"]["n"] for r in ok]
            walls = [r["tol"]["wall_s"] for r in everything]
            its = [r["tol"]["iterations"] for r in ok]
            lines.append(
                f"  n chosen: median {np.median(ns):.0f}, max {max(ns)}; iterations (all n) "
                f"{iteration_stats(its)}; wall median {np.median(walls) * 1e3:.1f} ms, "
                f"max {max(walls) * 1e3:.0f} ms, total {sum(walls):.1f} s"
            )
        for kind in sorted(kinds):
            errs = [
                r["tol"]["tip_error"]
                for r in ok
                if r["tip_type"] == kind and "tip_error" in r["tol"]
            ]
            back = [
                r["tol"]["backbone_error_vs_finest"]
                for r in ok
                if r["tip_type"] == kind and "backbone_error_vs_finest" in r["tol"]
            ]
            if errs:
                over = sum(e > tol for e in errs)
                over2 = sum(e > 2 * tol for e in errs)
                lines.append(
                    f"  {kind}: tip error / L against Richardson of the two finest fixed-n "
                    f"solves: median {np.median(errs):.1e}, max {max(errs):.1e}, "
                    f"> tol: {over}, > 2 tol: {over2} (of {len(errs)}); backbone error vs the "
                    f"finest fixed-n solve / L: median {np.median(back):.1e}, "
                    f"max {max(back):.1e}, > tol: {sum(b > tol for b in back)}"
                )
    return "\n".join(lines)


# A finer rod starts from a coarse rod's equilibrium (nested iteration): its
# count is the coarse rod's plus the fine Newton's (3 to 5).
FINE_NEWTON = 5


def growth_examples(records, factors, slack=FINE_NEWTON, limit=15):
    """Scenes whose iteration count at a finer n exceeds the base-n count +
    slack, or differs by more than 1 between the factors (grows with n)."""
    rows = []
    for r in records:
        if not r["base"]["converged"]:
            continue
        counts = [
            r["fine"][str(f)]["iterations"]
            for f in factors
            if r["fine"].get(str(f), {}).get("converged")
        ]
        if not counts:
            continue
        worst = max(counts) - r["base"]["iterations"]
        if worst > slack or max(counts) - min(counts) > 1:
            rows.append((worst, r))
    rows.sort(key=lambda x: -x[0])
    return [
        {
            "index": r["index"],
            "tip_type": r["tip_type"],
            "growth": worst,
            "base": {k: r["base"].get(k) for k in ("n", "iterations", "continuation_steps")},
            "fine": {
                f: {k: v.get(k) for k in ("n", "status", "iterations", "continuation_steps")}
                for f, v in r["fine"].items()
            },
            "base_message": r["base"]["message"],
            "scene": r["scene"],
        }
        for worst, r in rows[:limit]
    ], len(rows)


def jumps_of(records, factors, first=0.1, later=1e-3):
    """Converged fine solves that look like another equilibrium than the previous
    n's: the stability flag changed, or a node moved more than ``first`` L from
    the base solve (the base n's own discretisation error is up to a few % of L)
    or ``later`` L from the previous factor's (one branch: O(1/n^2))."""
    out = []
    for r in records:
        if not r["base"]["converged"]:
            continue
        prev = r["base"]
        for i, f in enumerate(factors):
            rec = r["fine"].get(str(f), {})
            if not rec.get("converged"):
                break
            diff = rec.get("node_diff_to_previous")
            limit = first if i == 0 else later
            if rec["stable"] != prev["stable"] or (diff is not None and diff > limit):
                out.append(
                    {
                        "index": r["index"],
                        "tip_type": r["tip_type"],
                        "from_n": prev["n"],
                        "to_n": rec["n"],
                        "node_diff": diff,
                        "stable": [prev["stable"], rec["stable"]],
                        "energy": [prev["energy"], rec["energy"]],
                        "messages": [prev["message"], rec["message"]],
                        "scene": r["scene"],
                    }
                )
            prev = rec
    return out


def failures_of(records, factors, tol):
    out = []
    for r in records:
        if not r["base"]["converged"]:
            continue
        for f in factors:
            rec = r["fine"].get(str(f))
            if rec is not None and not rec["converged"]:
                out.append(failure_entry(r, "fine", f, rec))
        if tol is not None and "tol" in r and not r["tol"]["converged"]:
            out.append(failure_entry(r, "tol", None, r["tol"]))
    return out


def failure_entry(record, kind, factor, rec):
    return {
        "index": record["index"],
        "kind": kind,
        "factor": factor,
        "n_elements": rec.get("n"),
        "status": rec["status"],
        "message": rec["message"],
        "iterations": rec["iterations"],
        "continuation_steps": rec["continuation_steps"],
        "wall_s": rec["wall_s"],
        "base": {
            k: record["base"].get(k)
            for k in ("n", "status", "iterations", "continuation_steps")
        },
        "scene": record["scene"],
    }


def git_head():
    try:
        out = subprocess.run(
            ["git", "rev-parse", "--short", "HEAD"], cwd=HERE, capture_output=True, text=True
        )
        return out.stdout.strip() or None
    except OSError:
        return None


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--scenes", type=int, default=599)
    parser.add_argument("--seed", type=int, default=11)
    parser.add_argument("--base-n", type=int, default=24, help="a multiple of 12 (1-4 sections)")
    parser.add_argument("--factors", type=int, nargs="+", default=[8, 32, 128])
    parser.add_argument("--tol", type=float, default=1e-6, help="accuracy on demand; 0: skip")
    parser.add_argument("--out", type=Path, help="write every record as JSON")
    parser.add_argument(
        "--failures",
        type=Path,
        default=HERE / "scale_failures.json",
        help="where the failing scenes go ('-' for nowhere)",
    )
    parser.add_argument(
        "--only", type=int, nargs="+", help="run these scene indices only (reproduce a scene)"
    )
    parser.add_argument("--quiet", action="store_true")
    args = parser.parse_args(argv)
    if args.base_n % 12:
        parser.error("--base-n must be a multiple of 12 (scenes have 1 to 4 sections)")
    tol = args.tol if args.tol > 0 else None
    factors = sorted(args.factors)

    start = time.perf_counter()
    records = []
    indices = args.only if args.only else range(args.scenes)
    for count, index in enumerate(indices):
        scene = make_scene(args.seed, index, args.base_n)
        record = study_scene(index, scene, args.base_n, factors, tol)
        records.append(record)
        if not args.quiet and (count + 1) % 50 == 0:
            print(
                f"  {count + 1} / {len(indices)} scenes, {time.perf_counter() - start:.0f} s",
                file=sys.stderr,
                flush=True,
            )
    elapsed = time.perf_counter() - start

    command = "python tools/scale_statistics.py " + " ".join(
        sys.argv[1:] if argv is None else argv
    )
    print(f"# {command}")
    print(
        f"# softspine {softspine.__version__} from {Path(softspine.__file__).parent}, "
        f"git {git_head()}, seed {args.seed}, "
        f"base n {args.base_n}, factors {factors}, tol {tol}; "
        f"python {platform.python_version()}; runtime {elapsed:.1f} s"
    )
    print(summarize(records, args.base_n, factors, tol))

    biggest = {
        f: max(
            (
                r["fine"][str(f)]["node_diff_to_previous"]
                for r in records
                if "node_diff_to_previous" in r["fine"].get(str(f), {})
            ),
            default=None,
        )
        for f in factors
    }
    print(
        "\nlargest node change / L from the previous n (the base n for the first factor; "
        "'-': the previous n does not divide this one): "
        + ", ".join(f"x{f}: {'-' if v is None else f'{v:.1e}'}" for f, v in biggest.items())
    )
    jumps = jumps_of(records, factors)
    print(
        "converged solves that look like another equilibrium than at the previous n "
        f"(stability changed, or a node moved > 0.1 L from the base / > 1e-3 L from the "
        f"previous factor): {len(jumps)}"
    )
    for j in jumps:
        diff = "-" if j["node_diff"] is None else f"{j['node_diff']:.3e} L"
        print(
            f"  scene {j['index']} ({j['tip_type']}) n={j['from_n']} -> {j['to_n']}: node diff "
            f"{diff}, stable {j['stable'][0]} -> {j['stable'][1]}, energy "
            f"{j['energy'][0]:.6g} -> {j['energy'][1]:.6g} J; {j['messages'][1]}"
        )

    growth, n_growth = growth_examples(records, factors)
    print(
        f"\nscenes converged at the base n whose iterations at some finer n (converged there) "
        f"exceed the base-n count + {FINE_NEWTON} or differ by more than 1 between the "
        f"factors: {n_growth} (the largest {len(growth)} below)"
    )
    for g in growth:
        fine = ", ".join(
            f"x{f}: {v['iterations']} ({v['continuation_steps']} steps"
            + ("" if v["status"] == "converged" else f", {v['status']}")
            + ")"
            for f, v in g["fine"].items()
        )
        print(
            f"  scene {g['index']} ({g['tip_type']}): base n={g['base']['n']}: "
            f"{g['base']['iterations']} ({g['base']['continuation_steps']} steps); {fine}"
        )

    failures = failures_of(records, factors, tol)
    print(f"\nfailing solves (converged at the base n, not here): {len(failures)}")
    for item in failures:
        where = f"x{item['factor']}" if item["kind"] == "fine" else f"tol={tol:g}"
        print(
            f"  scene {item['index']} ({tip_kind(item['scene'])}) {where} "
            f"n={item['n_elements']}: {item['status']} after {item['iterations']} iterations "
            f"({item['continuation_steps']} continuation steps): {item['message']}"
        )
    if str(args.failures) != "-":
        args.failures.write_text(
            json.dumps(
                {
                    "command": command,
                    "git": git_head(),
                    "softspine": str(Path(softspine.__file__).parent),
                    "seed": args.seed,
                    "base_n": args.base_n,
                    "failures": failures,
                    "base_not_converged": [
                        failure_entry(r, "base", None, r["base"])
                        for r in records
                        if not r["base"]["converged"]
                    ],
                    "branch_changes": jumps,
                    "iteration_growth": growth,
                },
                indent=1,
            )
            + "\n"
        )
        print(f"failing scenes written to {args.failures}")
    if args.out is not None:
        args.out.write_text(
            json.dumps(
                {
                    "command": command,
                    "git": git_head(),
                    "seed": args.seed,
                    "base_n": args.base_n,
                    "factors": factors,
                    "tol": tol,
                    "runtime_s": elapsed,
                    "records": records,
                }
            )
            + "\n"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
