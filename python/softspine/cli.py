"""Command line: ``softspine demo`` solves and plots the demo scene."""

from __future__ import annotations

import argparse
import sys
import time

import numpy as np

from . import solve
from .scenes import demo_robot_scene, load_scene


def _demo(args: argparse.Namespace) -> int:
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
    print(f"  base force [N]:   [{', '.join(f'{x:+.4f}' for x in sol.forces[0])}]")
    print(f"  energy: {sol.energy:.6f} J")
    fine = solve(scene, n_elements=8 * args.n_elements, method=args.method, initial=None)
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
    from .plotting import plot_backbones

    plot_backbones(
        [others[0], others[1], sol],
        args.out,
        labels=["actuation only (weightless)", "own weight", "own weight + tip load"],
        title=scene.name or "",
    )
    print(f"plot written to {args.out}")
    return 0 if sol.converged else 1


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="softspine", description=__doc__)
    sub = parser.add_subparsers(dest="command", required=True)
    demo = sub.add_parser("demo", help="solve and plot a scene (the demo robot by default)")
    demo.add_argument("--scene", help="a .json or .toml scene file")
    demo.add_argument("--n-elements", type=int, default=20)
    demo.add_argument("--method", default="newton", choices=["newton", "lm"])
    demo.add_argument("--out", default="softspine-demo.png", help="PNG file to write")
    demo.set_defaults(func=_demo)
    args = parser.parse_args(argv)
    try:
        return args.func(args)
    except ValueError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
