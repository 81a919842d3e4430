"""Throughput of many forward solves from Python, and the per-call overhead of
the reusable ``Solver`` over the Rust solve.

    python tools/batch_benchmark.py [--samples 10000]

The default robot (10 sections, n = 20) with 30 g at the tip, at random
actuations within the muscles' range (``Robot.workspace``'s samples). Each
figure is the best of three runs.
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np

import softspine

LOAD = 0.03


def best_of(runs: int, f) -> float:
    times = []
    for _ in range(runs):
        started = time.perf_counter()
        f()
        times.append(time.perf_counter() - started)
    return min(times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--samples", type=int, default=10_000)
    args = parser.parse_args()
    robot = softspine.Robot()
    k = robot.workspace(args.samples, LOAD, seed=1, progress=False).actuations
    n = len(k)
    loop = best_of(3, lambda: [robot.forward(x, LOAD) for x in k])
    one = best_of(3, lambda: robot.forward_batch(k, LOAD, threads=1, progress=False))
    every = best_of(3, lambda: robot.forward_batch(k, LOAD, progress=False))
    print(f"{n} forward solves, default robot (n = 20), {LOAD * 1e3:.0f} g, {os.cpu_count()} cores")
    print(f"  Python loop of Robot.forward   {loop:8.3f} s  ({loop / n * 1e6:5.1f} us a solve)")
    print(f"  forward_batch, one thread      {one:8.3f} s  ({one / n * 1e6:5.1f} us a solve)")
    print(f"  forward_batch, every core      {every:8.3f} s  ({every / n * 1e6:5.1f} us a solve)")
    print(f"  speed-up over one thread       {one / every:8.2f}")

    # A control loop: a slow sweep of the actuation, one Solver, warm starts.
    path = np.linspace(k[0], k[1], 2000)
    solver = softspine.Solver(robot.scene(k[0], LOAD), n_elements=robot.n_elements)
    solver.solve()
    rust = 0.0
    started = time.perf_counter()
    for x in path:
        solver.set_rest_curvature(x)
        rust += solver.solve().solve_time
    wall = time.perf_counter() - started
    per_call = wall / len(path) * 1e6
    overhead = (wall - rust) / len(path) * 1e6
    print(
        f"Solver control loop: {per_call:.1f} us a call (set_rest_curvature + solve), "
        f"{overhead:.2f} us of it outside the Rust solve"
    )


if __name__ == "__main__":
    main()
