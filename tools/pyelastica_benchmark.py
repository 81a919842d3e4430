"""softspine against PyElastica on the same rod-on-plane scene (issue 28).

A heavy rod, 1 m, EI = 1 N m^2, weight 1 N/m, radius 1 cm, clamped
horizontally with its axis 5 cm above a frictionless floor: its far part
lies on the floor. softspine solves the static equilibrium with exact
contact; PyElastica (a dynamic Cosserat rod simulator, its rod-plane contact
a penalty spring and damper) is damped to rest from the straight rod, and
timed until every node is within 1e-3 L of softspine's: the first time
they are (the kindest reading of its run), and from when they stay (at
rest). Not the tip alone: the tip falls onto the floor, within 1e-3 L of its
rest, long before the rod is at rest. The
same n = 80 elements in both. Numba's compilation is left out (a short
warm-up run first).

    pip install ".[bench]"
    python tools/pyelastica_benchmark.py

prints both times, their ratios, and the two tips.
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np

import softspine

LENGTH, EI, WEIGHT, RADIUS, LIFT, G = 1.0, 1.0, 1.0, 0.01, 0.05, 9.81


def softspine_answer(n: int, repeats: int) -> tuple[np.ndarray, float]:
    """The nodes' positions and the median time of a cold solve [s]."""
    scene = {
        "length": LENGTH,
        "stiffness": {"kx": EI, "ky": EI, "kz": EI},
        "gravity": {"linear_density": WEIGHT, "vector": [0.0, 0.0, -1.0]},
        "base_quaternion": [math.sqrt(0.5), 0.0, math.sqrt(0.5), 0.0],  # along +x
        "base_position": [0.0, 0.0, LIFT],
        "radius": RADIUS,
        "obstacles": [{"shape": "half_space", "point": [0, 0, 0], "normal": [0, 0, 1]}],
    }
    scene_object = softspine.Scene(scene)
    times = []
    for _ in range(repeats):
        started = time.perf_counter()
        sol = softspine.solve(scene_object, n_elements=n)
        times.append(time.perf_counter() - started)
    if not (sol.converged and sol.stable):
        raise RuntimeError(f"softspine: {sol.message}")
    return sol.positions, float(np.median(times))


def pyelastica_run(n: int, target: np.ndarray | None, final_time: float,
                   dt: float) -> tuple[np.ndarray, float, float, float]:
    """Integrate PyElastica's rod over `final_time` [s], checking every
    simulated millisecond whether every node is within 1e-3 L of `target`
    (n + 1 positions): the nodes at the end, and the wall times [s] at which
    they first came within it and from which they stayed (infinite if not),
    and the simulated time at which they stayed."""
    import elastica as ea

    class Simulator(ea.BaseSystemCollection, ea.Constraints, ea.Forcing, ea.Damping,
                    ea.Contact):
        pass

    sim = Simulator()
    area = math.pi * RADIUS**2
    inertia = math.pi * RADIUS**4 / 4.0
    density = WEIGHT / (G * area)
    youngs = EI / inertia
    rod = ea.CosseratRod.straight_rod(
        n, np.array([0.0, 0.0, LIFT]), np.array([1.0, 0.0, 0.0]),
        np.array([0.0, 0.0, 1.0]), LENGTH, RADIUS, density,
        youngs_modulus=youngs, shear_modulus=youngs / 3.0)
    sim.append(rod)
    sim.constrain(rod).using(ea.OneEndFixedBC, constrained_position_idx=(0,),
                             constrained_director_idx=(0,))
    sim.add_forcing_to(rod).using(ea.GravityForces, acc_gravity=np.array([0.0, 0.0, -G]))
    # About critical for the clamped rod's first bending mode.
    first_mode = 3.516 * math.sqrt(EI / (density * area * LENGTH**4))
    sim.dampen(rod).using(ea.AnalyticalLinearDamper, uniform_damping_constant=first_mode,
                          time_step=dt)
    plane = ea.Plane(plane_origin=np.zeros(3), plane_normal=np.array([0.0, 0.0, 1.0]))
    sim.append(plane)
    # A stiff penalty: the rod's weight on an element sinks it by 1e-5 L.
    stiffness = WEIGHT * LENGTH / n / (1e-5 * LENGTH)
    sim.detect_contact_between(rod, plane).using(ea.RodPlaneContact, k=stiffness,
                                                 nu=2.0 * math.sqrt(stiffness * density * area
                                                                    * LENGTH / n))
    sim.finalize()
    stepper = ea.PositionVerlet()
    t, check = 0.0, max(1, int(round(1e-3 / dt)))
    first = settled = settled_at = math.inf
    started = time.perf_counter()
    for k in range(int(round(final_time / dt))):
        t = stepper.step(sim, t, dt)
        if target is not None and k % check == 0:
            inside = distance(rod.position_collection.T, target) <= 1e-3 * LENGTH
            now = time.perf_counter() - started
            if inside and first == math.inf:
                first = now
            if inside and settled == math.inf:
                settled, settled_at = now, t
            elif not inside:
                settled = settled_at = math.inf
    return rod.position_collection.T.copy(), first, settled, settled_at


def distance(a: np.ndarray, b: np.ndarray) -> float:
    """The largest distance between corresponding nodes."""
    return float(np.linalg.norm(a - b, axis=1).max())


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--elements", type=int, default=80)
    parser.add_argument("--dt", type=float, default=1e-5, help="PyElastica's time step [s]")
    parser.add_argument("--max-time", type=float, default=3.0,
                        help="PyElastica's simulated time [s]")
    args = parser.parse_args()
    nodes, ours = softspine_answer(args.elements, 50)
    print(f"softspine: tip {np.round(nodes[-1], 5)} in {1e3 * ours:.2f} ms (median of 50)")
    pyelastica_run(args.elements, None, 100 * args.dt, args.dt)  # compile
    theirs, first, settled, settled_at = pyelastica_run(args.elements, nodes, args.max_time,
                                                        args.dt)
    miss = distance(theirs, nodes) / LENGTH
    print(f"PyElastica (dt = {args.dt:g} s, {args.max_time:g} s simulated): its farthest "
          f"node off ours by {miss:.1e} L at the end; within 1e-3 L first after "
          f"{first:.2f} s, for good after {settled:.2f} s ({settled_at:.3f} s simulated)")
    print(f"ratio: {first / ours:.0f} to the first time within, {settled / ours:.0f} to rest")

if __name__ == "__main__":
    main()
