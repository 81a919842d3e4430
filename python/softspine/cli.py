"""softspine's command line.

``softspine demo`` solves a scene (the demo robot by default), prints its tip,
reactions and timing and plots it; ``softspine track`` tracks a trajectory
(one of the seed's, or a CSV file) with load-aware inverse kinematics. Both
save their results as CSV or NPZ with ``--save``. Errors are one line.
"""

from __future__ import annotations

import argparse
import sys
import time
from typing import Any

import numpy as np

from . import Robot, SolverError, __version__, solve
from .plotting import require_matplotlib
from .scenes import demo_robot_scene, load_scene


def _check_outputs(args: argparse.Namespace) -> None:
    """Refuse a bad --save and a missing matplotlib before any work."""
    if args.save is not None:
        _save_format(args.save)
    if not args.no_plot:
        try:
            require_matplotlib()
        except ImportError as e:
            raise ImportError(f"{e}; or run with --no-plot") from e


def _save_format(path: str) -> str:
    suffix = path.rsplit(".", 1)[-1].lower() if "." in path else ""
    if suffix not in ("csv", "npz"):
        raise ValueError(f"--save: expected a .csv or .npz file, got {path!r}")
    return suffix


def _save_solution(sol, path: str) -> None:
    """The solution's arrays: NPZ holds the fields of ``to_dict()`` (those that
    are None left out), so that ``Solution.from_dict(dict(np.load(path)))``
    reads it back; CSV one row per node (arc length, position, quaternion,
    internal force and moment)."""
    if _save_format(path) == "npz":
        fields = {k: v for k, v in sol.to_dict().items() if v is not None}
        np.savez(path, **fields)
        return
    table = np.column_stack([sol.arc_length, sol.positions, sol.quaternions,
                             sol.forces, sol.moments])
    header = "s,x,y,z,qw,qx,qy,qz,Fx,Fy,Fz,Mx,My,Mz"
    np.savetxt(path, table, delimiter=",", header=header, comments="", fmt="%.17g")


def _actuation_columns(robot: Robot, results) -> tuple[str, np.ndarray, list[str]]:
    """The actuation the IK searched, one row a target, with its CSV names:
    rest curvature per section, tendon tensions or the field."""
    space = robot.actuation_space
    if space == "tensions":
        values = np.array([r.tensions for r in results])
        return space, values, [f"tension{i}" for i in range(values.shape[1])]
    if space == "field":
        values = np.array([r.field for r in results])
        return space, values, [f"B{c}" for c in "xyz"]
    values = np.array([r.rest_curvature for r in results])
    names = [f"kappa{k}_{c}" for k in range(values.shape[1]) for c in "xy"]
    return "rest_curvature", values.reshape(len(results), -1), names


def _save_track(robot: Robot, points: np.ndarray, results, path: str) -> None:
    """One row per target: the target, the tip reached, the miss, how it ended,
    and the actuation (rest curvature per section, tensions or field)."""
    tips = np.array([r.tip_position for r in results])
    misses = np.array([r.tip_miss for r in results])
    reached = np.array([r.reached for r in results])
    endings = np.array([str(r.ending) for r in results])
    name, actuation, columns = _actuation_columns(robot, results)
    if _save_format(path) == "npz":
        arrays: dict[str, Any] = {
            "targets": points, "tips": tips, "tip_miss": misses, "reached": reached,
            "ending": endings, "time": np.array([r.time for r in results]),
        }
        if name == "rest_curvature":
            arrays["rest_curvature"] = np.array([r.rest_curvature for r in results])
            arrays["muscle_lengths"] = np.array([r.muscle_lengths for r in results])
        else:
            arrays[name] = actuation
        np.savez(path, **arrays)
        return
    header = ["target_x", "target_y", "target_z", "tip_x", "tip_y", "tip_z", "tip_miss",
              "reached", "ending", *columns]
    with open(path, "w", encoding="utf-8") as f:
        f.write(",".join(header) + "\n")
        for i in range(len(results)):
            row = [*(f"{x:.17g}" for x in (*points[i], *tips[i], misses[i])),
                   str(bool(reached[i])), endings[i],
                   *(f"{x:.17g}" for x in actuation[i])]
            f.write(",".join(row) + "\n")


def _demo(args: argparse.Namespace) -> int:
    _check_outputs(args)
    scene = load_scene(args.scene) if args.scene else demo_robot_scene()
    print(f"scene: {scene.name or args.scene}")
    print(f"  length {scene.length} m, sections {scene.sections}, "
          f"stiffness kx, ky, kz = {', '.join(f'{k:.4g}' for k in scene.stiffness)} N m^2")
    sol = solve(scene, n_elements=args.n_elements, method=args.method)
    repeats = 200
    t0 = time.perf_counter()
    for _ in range(repeats):
        solve(scene, n_elements=args.n_elements, method=args.method)
    cold_us = (time.perf_counter() - t0) / repeats * 1e6
    print(f"solve ({args.method}, n = {sol.n_elements}): {sol.message}; "
          f"{sol.iterations} iterations, residual {sol.residual_norm:.1e}, "
          f"stable: {sol.stable}")
    print(f"  time per solve from the straight guess: {cold_us:.0f} us "
          f"(Python call included, mean of {repeats})")
    tip = sol.tip_position
    print(f"  tip position [m]: [{tip[0]:+.5f}, {tip[1]:+.5f}, {tip[2]:+.5f}]")
    print(f"  tip quaternion:   [{', '.join(f'{x:+.5f}' for x in sol.tip_quaternion)}]")
    # forces[0]: the force of the rod on its base support (the reaction is minus it).
    print(f"  force on the base support [N]: "
          f"[{', '.join(f'{x:+.4f}' for x in sol.forces[0])}]")
    print(f"  energy: {sol.energy:.6f} J")
    fine = solve(scene, n_elements=8 * sol.n_elements, method=args.method, initial=None)
    err = float(np.linalg.norm(fine.tip_position - tip))
    print(f"  tip difference to n = {fine.n_elements}: {err * 1e3:.3f} mm")
    # What the load does: the same actuation without weight and without the tip load.
    weightless = scene.to_dict()
    weightless.pop("gravity", None)
    weightless["distributed_force"] = [0.0, 0.0, 0.0]
    weightless["tip_force"] = [0.0, 0.0, 0.0]
    own_weight = scene.to_dict()
    own_weight["tip_force"] = [0.0, 0.0, 0.0]
    others = [
        solve(d, n_elements=args.n_elements, method=args.method) for d in (weightless, own_weight)
    ]
    sag = float(np.linalg.norm(tip - others[0].tip_position))
    print(f"  the loads move the tip by {sag * 1e3:.1f} mm from its weightless position")
    if args.save is not None:
        _save_solution(sol, args.save)
        print(f"solution written to {args.save}")
    if not args.no_plot:
        from .plotting import plot_backbones

        plot_backbones(
            [others[0], others[1], sol],
            args.out,
            labels=["actuation only (weightless)", "own weight", "own weight + tip load"],
            title=scene.name or "",
        )
        print(f"plot written to {args.out}")
    return 0 if sol.converged else 1


def _progress(done: int, total: int, width: int = 30) -> None:
    if not sys.stdout.isatty():
        return
    filled = width * done // total
    sys.stdout.write(f"\r  [{'#' * filled}{'.' * (width - filled)}] {done}/{total}")
    sys.stdout.flush()
    if done == total:
        sys.stdout.write("\n")


def _read_points(path: str) -> np.ndarray:
    """Targets from a CSV file: x, y, z in m per row (a header line is skipped)."""
    with open(path, encoding="utf-8") as f:
        lines = [line for line in f.read().splitlines() if line.strip()]
    if lines and lines[0].lstrip()[0] not in "+-.0123456789":
        lines = lines[1:]
    rows = []
    for k, line in enumerate(lines):
        try:
            row = [float(x) for x in line.replace(";", ",").split(",")]
        except ValueError:
            raise ValueError(f"{path}: line {k + 1}: expected three numbers x, y, z") from None
        if len(row) != 3:
            raise ValueError(f"{path}: line {k + 1}: expected three numbers x, y, z, "
                             f"got {len(row)}")
        rows.append(row)
    if not rows:
        raise ValueError(f"{path}: no points")
    return np.array(rows)


def _track(args: argparse.Namespace) -> int:
    from . import trajectories

    _check_outputs(args)
    robot = Robot.from_file(args.robot) if args.robot else Robot()
    if args.trajectory in trajectories.NAMES:
        # The seed's trajectory, placed at the robot (scaled to its length).
        points = trajectories.by_name(args.trajectory, args.points, robot)
    else:
        points = _read_points(args.trajectory)
    space = robot.actuation_space
    print(f"{args.trajectory}: {len(points)} points, {args.load * 1e3:.0f} g at the tip, "
          f"{robot.sections}-section robot, n = {robot.n_elements}, "
          f"IK in {space} space" + (f", strategy {args.strategy}" if space == "curvature" else ""))
    geometric = None
    results = []
    if space != "curvature":
        if args.strategy != "equilibrium":
            raise ValueError(f"strategy: {args.strategy} fits muscle curvatures; this robot's "
                             f"actuation is its {space}")
        # Each point warm from the last answer.
        last = None
        for i, p in enumerate(points):
            r = robot.inverse(p, load=args.load, initial=last)
            last = r if r.solution.stable else None
            results.append(r)
            _progress(i + 1, len(points))
    else:
        solver = robot.inverse_solver(args.load)
        reference = None
        for i, p in enumerate(points):
            if args.strategy == "equilibrium":
                r = solver.solve(p, reference=reference)
            else:
                r = robot.inverse(p, load=args.load, reference=reference, strategy="geometric")
            reference = r.rest_curvature
            results.append(r)
            _progress(i + 1, len(points))
        if args.strategy == "equilibrium":
            geometric = robot.track(points, load=args.load, strategy="geometric")
    misses = np.array([r.tip_miss for r in results])
    times = np.array([r.time for r in results])
    reached = sum(r.reached for r in results)
    print(f"  reached {reached}/{len(points)}; tip miss max {misses.max():.2e} m, "
          f"median {np.median(misses):.2e} m")
    print(f"  time per point: median {np.median(times) * 1e6:.0f} us, "
          f"max {times.max() * 1e6:.0f} us; whole trajectory {times.sum() * 1e3:.1f} ms")
    if geometric is not None:
        g = np.array([r.tip_miss for r in geometric])
        print(f"  the geometric (load-ignoring) actuation would miss by up to "
              f"{g.max() * 100:.1f} cm "
              f"(median {np.median(g) * 100:.1f} cm)")
    for r in results:
        if not r.reached:
            print(f"  {r.message}")
    if args.save is not None:
        _save_track(robot, points, results, args.save)
        print(f"results written to {args.save}")
    if not args.no_plot:
        from .plotting import plot_tracking

        plot_tracking(points, results, args.out,
                      title=f"{args.trajectory}, {args.load * 1e3:.0f} g at the tip",
                      geometric=geometric)
        print(f"plot written to {args.out}")
    return 0 if reached == len(points) else 1


def _table(args: argparse.Namespace) -> int:
    """Every trajectory with 0, 30 and 60 g: a Markdown table (docs/reference.md)."""
    from . import trajectories

    robot = Robot()
    print("| trajectory | load | reached | tip miss, max | IK per point, median | "
          "whole trajectory | geometric IK misses by | IK for 0 g misses by |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|")
    for name in trajectories.NAMES:
        points = trajectories.by_name(name, args.points)
        unloaded = robot.track(points, load=0.0)
        for load in (0.0, 0.03, 0.06):
            # Best of three runs of the whole trajectory (timing noise of a shared machine).
            runs = [robot.track(points, load=load) for _ in range(3)]
            results = min(runs, key=lambda rs: sum(r.time for r in rs))
            times = np.array([r.time for r in results])
            misses = np.array([r.tip_miss for r in results])
            geometric = robot.track(points, load=load, strategy="geometric")
            g = np.array([r.tip_miss for r in geometric])
            zero = np.array([
                np.linalg.norm(robot.forward(r.rest_curvature, load=load).tip_position - p)
                for r, p in zip(unloaded, points, strict=True)
            ])
            reached = sum(r.reached for r in results)
            print(f"| {name} | {load * 1e3:.0f} g | {reached}/{len(points)} "
                  f"| {misses.max():.1e} m | {np.median(times) * 1e6:.0f} us "
                  f"| {times.sum() * 1e3:.1f} ms | {np.median(g) * 100:.1f} cm "
                  f"(max {g.max() * 100:.1f}) | {np.median(zero) * 100:.1f} cm "
                  f"(max {zero.max() * 100:.1f}) |")
    return 0


def main(argv: list[str] | None = None) -> int:
    formatter = argparse.ArgumentDefaultsHelpFormatter
    parser = argparse.ArgumentParser(prog="softspine", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--version", action="version", version=f"softspine {__version__}")
    sub = parser.add_subparsers(dest="command", required=True)
    demo = sub.add_parser("demo", formatter_class=formatter,
                          help="solve, print and plot a scene (the demo robot by default)",
                          description="Solve a scene, print its tip, base force, energy and "
                          "time per solve, and plot it with and without its loads.")
    demo.add_argument("--scene", metavar="FILE",
                      help="a .json or .toml scene file (default: the demo robot, 10 sections, "
                      "own weight and 30 g)")
    demo.add_argument(
        "--n-elements", type=int, default=None, metavar="N",
        help="elements (default: the smallest multiple of the sections that is at least 20)")
    demo.add_argument("--method", default="newton", choices=["newton", "lm"],
                      help="the numerical method")
    demo.add_argument("--out", default="softspine-demo.png", metavar="PNG",
                      help="the plot to write")
    demo.add_argument("--no-plot", action="store_true", help="write no plot (no matplotlib)")
    demo.add_argument("--save", metavar="FILE",
                      help="also write the solution: .npz (every field) or .csv (a row a node: "
                      "s, position, quaternion, internal force and moment)")
    demo.set_defaults(func=_demo)
    track = sub.add_parser("track", formatter_class=formatter,
                           help="track a trajectory with load-aware inverse kinematics",
                           description="Find, point after point, the actuation whose loaded "
                           "tip reaches each target; print the misses and times; plot.")
    track.add_argument("--trajectory", default="circle", metavar="NAME|FILE.csv",
                       help="pentagram, circle, spiral (the seed's), or a CSV file of x, y, z "
                       "in m per row")
    track.add_argument("--robot", metavar="FILE",
                       help="a .json or .toml robot description (default: the seed's "
                       "10-section robot; fields as Robot().to_dict())")
    track.add_argument("--load", type=float, default=0.03, help="tip mass, kg")
    track.add_argument("--points", type=int, default=60,
                       help="points of a named trajectory")
    track.add_argument("--strategy", default="equilibrium", choices=["equilibrium", "geometric"],
                       help="equilibrium: the loaded robot reaches the target; geometric: "
                       "the seed's fit that ignores the load")
    track.add_argument("--out", default="softspine-track.png", metavar="PNG",
                       help="the plot to write")
    track.add_argument("--no-plot", action="store_true", help="write no plot (no matplotlib)")
    track.add_argument("--save", metavar="FILE",
                       help="also write the results: .csv (a row a target: target, tip, miss, "
                       "ending, rest curvature) or .npz")
    track.set_defaults(func=_track)
    table = sub.add_parser("track-table", formatter_class=formatter,
                           help="every seed trajectory with 0, 30 and 60 g: a Markdown table")
    table.add_argument("--points", type=int, default=60, help="points per trajectory")
    table.set_defaults(func=_table)
    args = parser.parse_args(argv)
    try:
        return args.func(args)
    except (ValueError, OSError, SolverError, ImportError) as e:
        # A user error (bad scene or argument, missing file, a missing extra):
        # one line, like argparse.
        message = " ".join(str(e).split()) or type(e).__name__
        print(f"{parser.prog}: error: {message}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
