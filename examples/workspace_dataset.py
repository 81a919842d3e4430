"""A million-sample workspace dataset of the seed's robot (30 g at the tip):
random actuations within the muscles' range and their loaded equilibria,
written to a compressed NPZ file (for a learned model, a reachability map).

Run: ``python examples/workspace_dataset.py [OUT] [--samples N] [--dask WORKERS]``

On this machine's two cores a million samples take about 10 s locally. With
``--dask`` the same batch runs on a local Dask cluster (a ``Client`` of a real
cluster works the same way, and so does ``executor=ray`` after ``ray.init``);
the dataset is the same, bit for bit.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

import softspine


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", nargs="?", default="workspace.npz", type=Path)
    parser.add_argument("--samples", type=int, default=1_000_000)
    parser.add_argument("--dask", type=int, metavar="WORKERS", help="run on a local Dask cluster")
    args = parser.parse_args()
    out = args.out.with_suffix(".npz")
    robot = softspine.Robot()
    executor = None
    if args.dask:
        from distributed import Client, LocalCluster

        executor = Client(LocalCluster(n_workers=args.dask, threads_per_worker=1))
    started = time.perf_counter()
    # A progress bar on a terminal; Ctrl-C stops the batch.
    ws = robot.workspace(args.samples, load=0.03, seed=1, executor=executor)
    elapsed = time.perf_counter() - started
    assert ws.actuations is not None  # a robot's batch carries its actuations
    np.savez_compressed(
        out,
        actuations=ws.actuations,
        tip_positions=ws.tip_positions,
        tip_quaternions=ws.tip_quaternions,
        status=ws.status,
        stable=ws.stable,
    )
    good = int((ws.converged & ws.stable).sum())
    print(
        f"{len(ws)} samples in {elapsed:.1f} s ({len(ws) / elapsed:,.0f} a second): "
        f"{good} converged and stable; written to {out}"
    )
    reach = np.linalg.norm(ws.tip_positions[:, :2], axis=1)
    print(
        f"horizontal reach of the tip: up to {reach.max():.3f} m, median {np.median(reach):.3f} m"
    )
    if executor is not None:
        executor.close()


if __name__ == "__main__":
    main()
