"""Prototype of the contact formulation (issue 28, deliverable 3: prototype
and measure before choosing), planar, in NumPy/SciPy.

A heavy inextensible rod on a rigid frictionless table (y >= 0) with one end
lifted to a height h, solved as a constrained equilibrium in the *mixed*
form: node positions, element angles, the elements' internal forces (the
kinematic rows' multipliers) and the nodes' contact forces are all unknowns,
interleaved node by node, so the Newton matrix is banded whatever the number
of contacts. The contacts are a primal-dual active set (a node is active when
`lambda - c y > 0`); Newton on the equations with the active set fixed, the
set updated until it repeats.

The alternative, the current held-point machinery (positions eliminated,
each contact a row of `D = dr/dtheta`, dense below the diagonal, and a Schur
complement over the contact rows), costs O(n m) a step in memory and O(n m^2)
in time for m contacts: a rod lying on a floor has m ~ n.

    python tools/contact_prototype.py            # accuracy and cost tables

Prints the lifted length against the closed forms `(24 EI h / w)^(1/4)`
(end lifted by a force) and `(72 EI h / w)^(1/4)` (end held horizontal) as
n grows, and the time of a solve against n with every node in contact.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

# Unknowns, interleaved: node k holds (x, y, lambda) at 6 k, element e >= 1
# holds (phi, Nx, Ny) at 6 e - 3.
X, Y, LAM = 0, 1, 2
PHI, NX, NY = 0, 1, 2


def node(k: int, c: int) -> int:
    return 6 * k + c


def elem(e: int, c: int) -> int:
    return 6 * e - 3 + c


def equations(u: np.ndarray, n: int, length: float, ei: float, w: float, lift: float,
              horizontal: bool, active: np.ndarray) -> tuple[np.ndarray, sp.csr_matrix]:
    """The residual and its Jacobian (sparse, banded) at `u`, the active set fixed."""
    h = length / n
    size = 6 * n + 3
    res = np.zeros(size)
    rows: list[int] = []
    cols: list[int] = []
    vals: list[float] = []

    def add(r: int, c: int, v: float) -> None:
        rows.append(r)
        cols.append(c)
        vals.append(v)

    phi = np.array([0.0] + [u[elem(e, PHI)] for e in range(1, n + 1)])
    weight = np.full(n + 1, w * h)
    weight[[0, n]] = 0.5 * w * h
    # Element rows: bending stationarity in phi_e, and the two kinematic rows.
    for e in range(1, n + 1):
        r = elem(e, PHI)
        nx, ny = u[elem(e, NX)], u[elem(e, NY)]
        s, c = np.sin(phi[e]), np.cos(phi[e])
        if horizontal and e == n:
            res[r] = phi[e]  # the end held horizontal
            add(r, r, 1.0)
        else:
            k = ei / h
            for other in (e - 1, e + 1):
                if 1 <= other <= n:
                    res[r] += k * (phi[e] - phi[other])
                    add(r, elem(e, PHI), k)
                    add(r, elem(other, PHI), -k)
            # + N . h t'(phi), t' = (-sin, cos)
            res[r] += h * (-nx * s + ny * c)
            add(r, elem(e, PHI), h * (-nx * c - ny * s))
            add(r, elem(e, NX), -h * s)
            add(r, elem(e, NY), h * c)
        # x_e - x_(e-1) - h cos = 0, y_e - y_(e-1) - h sin = 0
        rx, ry = elem(e, NX), elem(e, NY)
        res[rx] = u[node(e, X)] - u[node(e - 1, X)] - h * c
        add(rx, node(e, X), 1.0)
        add(rx, node(e - 1, X), -1.0)
        add(rx, elem(e, PHI), h * s)
        res[ry] = u[node(e, Y)] - u[node(e - 1, Y)] - h * s
        add(ry, node(e, Y), 1.0)
        add(ry, node(e - 1, Y), -1.0)
        add(ry, elem(e, PHI), -h * c)
    # Node rows: force balance in x and y, and the contact's row.
    for k in range(n + 1):
        rx, ry, rl = node(k, X), node(k, Y), node(k, LAM)
        if k == 0:
            res[rx] = u[rx]  # the far end held horizontally (a frictionless table)
            add(rx, rx, 1.0)
        else:
            res[rx] = -u[elem(k, NX)]
            add(rx, elem(k, NX), -1.0)
            if k < n:
                res[rx] += u[elem(k + 1, NX)]
                add(rx, elem(k + 1, NX), 1.0)
        if k == n:
            res[ry] = u[ry] - lift  # lifted: its force is what the row leaves over
            add(ry, ry, 1.0)
        else:
            res[ry] = weight[k] - u[rl]
            add(ry, rl, -1.0)
            if k >= 1:
                res[ry] -= u[elem(k, NY)]
                add(ry, elem(k, NY), -1.0)
            res[ry] += u[elem(k + 1, NY)]
            add(ry, elem(k + 1, NY), 1.0)
        if active[k]:
            res[rl] = u[ry]  # on the table
            add(rl, ry, 1.0)
        else:
            res[rl] = u[rl]  # off it: no contact force
            add(rl, rl, 1.0)
    jac = sp.csr_matrix((vals, (rows, cols)), shape=(size, size))
    return res, jac


def solve(n: int, length: float, ei: float, w: float, lift: float, horizontal: bool,
          steps: int = 4) -> tuple[np.ndarray, np.ndarray, int]:
    """The equilibrium lifted to `lift` in `steps` stages from the rod lying
    flat: the unknowns, the active set and the Newton iterations in all."""
    h = length / n
    u = np.zeros(6 * n + 3)
    for k in range(n + 1):
        u[node(k, X)] = k * h
        u[node(k, LAM)] = w * h
    # Off the table from the start: what the small-slope theory lifts at the
    # first stage (at least the end, and held horizontal the node before it).
    first = (24.0 * ei * lift / steps / w) ** 0.25
    off = max(2 if horizontal else 1, int(np.ceil(first / h)))
    active = np.ones(n + 1, dtype=bool)
    active[max(0, n + 1 - off):] = False
    iterations = 0
    for stage in range(1, steps + 1):
        target = lift * stage / steps
        for _ in range(50):
            for _newton in range(30):
                res, jac = equations(u, n, length, ei, w, target, horizontal, active)
                du = spla.spsolve(jac.tocsc(), -res)
                # Damped: no element turns by more than 0.2 rad a step.
                turn = np.abs(du[elem(1, PHI)::6][:n]).max()
                u += du * min(1.0, 0.2 / turn) if turn > 0 else du
                iterations += 1
                if np.abs(du).max() < 1e-13 * length:
                    break
            y = u[node(0, Y)::6][: n + 1]
            lam = u[node(0, LAM)::6][: n + 1]
            scale = w * h / length
            new = lam - scale * y > 0
            new[n] = False
            if horizontal:
                new[n - 1] = False
            if np.array_equal(new, active):
                break
            active = new
    return u, active, iterations


def lifted_length(u: np.ndarray, active: np.ndarray, n: int, length: float) -> float:
    """From the last node on the table to the lifted end."""
    h = length / n
    last = np.flatnonzero(active).max()
    return length - last * h


def main() -> None:
    ei, w, length = 1.0, 1.0, 2.0
    print("lifted length against the small-deflection closed forms, h = 1e-4 (EI = w = 1, L = 2)")
    print("| end | n | lifted length | closed form | error / grid step "
          "| lifting force / (w a / 2) |")
    print("|---|---:|---:|---:|---:|---:|")
    lift = 1e-4
    for horizontal, factor in ((False, 24.0), (True, 72.0)):
        exact = (factor * ei * lift / w) ** 0.25
        for n in (50, 100, 200, 400):
            u, active, _ = solve(n, length, ei, w, lift, horizontal)
            a = lifted_length(u, active, n, length)
            # What the lifted end's force balance leaves over: the lifting force.
            force = 0.5 * w * length / n - u[elem(n, NY)]
            ratio = f"{force / (0.5 * w * exact):.4f}" if not horizontal else "-"
            print(f"| {'horizontal' if horizontal else 'force'} | {n} | {a:.4f} | {exact:.4f} "
                  f"| {(a - exact) / (length / n):+.2f} | {ratio} |")
    print()
    # A large lift against the shooting reference with the lift-off point
    # as an unknown (tests/contact_reference.py): no small-slope theory.
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))
    from contact_reference import lifted_rod

    lift, length = 0.3, 3.0
    a_ref, force_ref = lifted_rod(ei, w, lift)
    print(f"a large lift (h = {lift}, L = {length}) against shooting: a = {a_ref:.5f}, "
          f"lifting force {force_ref:.5f}")
    print("| n | lifted length | error / grid step | lifting force, relative error |")
    print("|---:|---:|---:|---:|")
    for n in (100, 200, 400, 800):
        u, active, _ = solve(n, length, ei, w, lift, False, steps=16)
        a = lifted_length(u, active, n, length)
        force = 0.5 * w * length / n - u[elem(n, NY)]
        print(f"| {n} | {a:.5f} | {(a - a_ref) / (length / n):+.2f} "
              f"| {(force - force_ref) / force_ref:+.1e} |")
    print()
    print("cost of one Newton step with every node on the table (banded, sparse LU)")
    print("| n | contacts | ms a step |")
    print("|---:|---:|---:|")
    for n in (200, 400, 800, 1600, 3200):
        h = length / n
        u = np.zeros(6 * n + 3)
        for k in range(n + 1):
            u[node(k, X)] = k * h
        active = np.ones(n + 1, dtype=bool)
        active[n] = False
        res, jac = equations(u, n, length, ei, w, 0.0, False, active)
        started = time.perf_counter()
        for _ in range(5):
            spla.spsolve(jac.tocsc(), -res)
        print(f"| {n} | {n} | {(time.perf_counter() - started) / 5 * 1e3:.2f} |")


if __name__ == "__main__":
    main()
