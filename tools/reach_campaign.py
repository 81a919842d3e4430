"""The reach test of issue 27, seeded, to rerun on any build: for each robot,
targets made by forward solves of random admissible drives (the robot's own
workspace sampler: muscle lengths, tensions or fields within their limits),
then the inverse kinematics of each target from the robot's default start.
A target made this way is reachable by construction; every miss is counted
with its ending.

    python tools/reach_campaign.py              # 150 targets a robot
    python tools/reach_campaign.py --targets 30 --robots tendon catheter
    python tools/reach_campaign.py --pose       # the tip's whole pose as the goal

Prints, per robot: targets reached, the endings of the others, and the IK
time per point (median and 95th percentile, one core).
"""

from __future__ import annotations

import argparse
import math
import time
from collections import Counter
from pathlib import Path

import numpy as np

import softspine

ROOT = Path(__file__).resolve().parent.parent


def robots() -> dict[str, tuple[softspine.Robot, float]]:
    """The issue's robots and the payload [kg] each carries."""
    half = 0.25  # half the tilt [rad] about the x axis
    tilted = softspine.Robot({"base_quaternion": [math.cos(half), math.sin(half), 0.0, 0.0]})
    example = ROOT / "examples" / "robots"
    return {
        "pneumatic": (softspine.Robot(), 0.0),
        "tilted": (tilted, 0.0),
        "tendon": (softspine.Robot.from_file(example / "tendon_robot.toml"), 0.0),
        "catheter": (softspine.Robot.from_file(example / "magnetic_catheter.toml"), 0.0),
        "three_sections_30g": (softspine.Robot({"sections": 3, "n_elements": 18}), 0.03),
    }


def reach(robot: softspine.Robot, load: float, count: int, seed: int,
          pose: bool = False) -> dict:
    """The IK of `count` targets drawn from the robot's admissible drives
    (seeded): the targets, which were reached, each ending and the seconds.
    With `pose`, each target is the tip's position and orientation."""
    drawn = robot.workspace(count, load, seed=seed, threads=1, progress=False)
    usable = (drawn.status == "converged") & drawn.stable
    out: dict = {"targets": drawn.tip_positions[usable], "drawn": int(count),
                 "results": [], "seconds": []}
    for target, turn in zip(out["targets"], drawn.tip_quaternions[usable], strict=True):
        started = time.perf_counter()
        if pose:
            out["results"].append(robot.inverse(target, load, orientation=turn))
        else:
            out["results"].append(robot.inverse(target, load))
        out["seconds"].append(time.perf_counter() - started)
    return out


def campaign(name: str, robot: softspine.Robot, load: float, count: int, seed: int,
             pose: bool = False) -> None:
    found = reach(robot, load, count, seed, pose)
    misses = [r for r in found["results"] if not r.reached]
    endings = Counter(str(r.ending) for r in misses)
    times = np.array(found["seconds"]) * 1e3
    worst = f", misses up to {max(r.tip_miss for r in misses) * 1e3:.1f} mm" if misses else ""
    total = len(found["targets"])
    print(f"{name:20s} {total - len(misses):3d} of {total} reached "
          f"({count - total} draws not a stable equilibrium); "
          f"IK per point median {np.median(times):.1f} ms, 95 % {np.percentile(times, 95):.1f} ms; "
          f"endings of the misses {dict(endings)}{worst}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--targets", type=int, default=150)
    parser.add_argument("--seed", type=int, default=27)
    parser.add_argument("--robots", nargs="*", default=None)
    parser.add_argument("--pose", action="store_true",
                        help="aim at each tip's orientation too (a full pose)")
    args = parser.parse_args()
    for name, (robot, load) in robots().items():
        if args.robots and name not in args.robots:
            continue
        campaign(name, robot, load, args.targets, args.seed, args.pose)


if __name__ == "__main__":
    main()
