"""Write the reference page's time-to-accuracy table from `cargo bench --bench accuracy`.

    cargo bench --bench accuracy 2>&1 | tee /tmp/accuracy.txt
    python tools/accuracy_table.py /tmp/accuracy.txt --readme docs/reference.md

The bench prints `error <scene> <kind> n=<n>: <error>` (largest node distance
from the reference over L) and then Criterion's medians; for each scene, kind
and error level the table gives the time of the smallest n that reaches it.
"""

from __future__ import annotations

import argparse
import re
from pathlib import Path

LEVELS = (1e-4, 1e-6, 1e-8)
SCENES = {
    "cantilever_alpha3": "cantilever alpha = 3",
    "cantilever_alpha10": "cantilever alpha = 10",
    "robot_30g": "default robot, 3D actuation, 30 g",
}
KINDS = {
    "newton_fd2": "Newton, fd2",
    "newton_fe4": "Newton, fe4",
    "shooting": "shooting (RK4)",
}
UNITS = {"ns": 1e-9, "µs": 1e-6, "us": 1e-6, "ms": 1e-3, "s": 1.0}
BEGIN, END = "<!-- accuracy-table -->", "<!-- /accuracy-table -->"


def parse(text: str) -> tuple[dict, dict]:
    """Errors and median times [s], keyed by (scene, kind, n)."""
    errors = {
        (m[1], m[2], int(m[3])): float(m[4])
        for m in re.finditer(r"^error (\S+) (\S+) n=(\d+): (\S+)$", text, re.M)
    }
    times = {}
    pattern = r"^accuracy/(\S+)/(\S+)/(\d+)\s+time:\s+\[\S+ \S+ (\S+) (\S+) \S+ \S+\]"
    for m in re.finditer(pattern, text, re.M):
        times[(m[1], m[2], int(m[3]))] = float(m[4]) * UNITS[m[5]]
    return errors, times


def cell(errors: dict, times: dict, scene: str, kind: str, level: float) -> str:
    sizes = sorted(n for (s, k, n) in errors if (s, k) == (scene, kind))
    for n in sizes:
        if errors[(scene, kind, n)] <= level and (scene, kind, n) in times:
            return f"{times[(scene, kind, n)] * 1e6:.0f} us (n = {n})"
    return f"n > {sizes[-1]}" if sizes else "-"


def table(errors: dict, times: dict) -> str:
    rows = [
        "| scene | backbone error | " + " | ".join(KINDS.values()) + " |",
        "|---|---:|" + "---:|" * len(KINDS),
    ]
    for scene, label in SCENES.items():
        for level in LEVELS:
            cells = [cell(errors, times, scene, kind, level) for kind in KINDS]
            rows.append(f"| {label} | {level:g} L | " + " | ".join(cells) + " |")
    return "\n".join(rows)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("bench_output", type=Path)
    parser.add_argument("--readme", type=Path, help="rewrite the table in this file")
    args = parser.parse_args()
    errors, times = parse(args.bench_output.read_text())
    text = table(errors, times)
    print(text)
    if args.readme:
        readme = args.readme.read_text()
        start, end = readme.index(BEGIN) + len(BEGIN), readme.index(END)
        args.readme.write_text(readme[:start] + "\n" + text + "\n" + readme[end:])


if __name__ == "__main__":
    main()
