"""The examples run as a user runs them, and plotting leaves matplotlib's
backend alone."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import matplotlib
import numpy as np
import pytest

import softspine
from softspine.plotting import plot_backbone

EXAMPLES = sorted((Path(__file__).parent.parent / "examples").glob("*.py"))


def test_there_are_examples():
    assert len(EXAMPLES) >= 3


def test_the_gallery_shows_every_examples_figure():
    # Issue 29, item 7: an example that draws a figure has it in docs/ under
    # its own name, where the gallery (docs/hooks/gallery.py) shows it.
    drawing = [p for p in EXAMPLES if "savefig" in p.read_text(encoding="utf-8")]
    assert len(drawing) >= 4
    missing = [p.name for p in drawing if not (p.parent.parent / "docs" / f"{p.stem}.png").exists()]
    assert not missing, f"run each with its figure's path docs/<name>.png: {missing}"


@pytest.mark.slow
@pytest.mark.parametrize("path", EXAMPLES, ids=lambda p: p.name)
def test_example_runs(path, tmp_path):
    done = subprocess.run(
        [sys.executable, str(path), str(tmp_path / "out.png")],
        cwd=tmp_path, capture_output=True, text=True, timeout=300,
    )
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip()


def test_plot_backbone_returns_axes_and_keeps_the_backend():
    import matplotlib.pyplot as plt

    backend = matplotlib.get_backend()
    sol = softspine.solve({"length": 1.0, "stiffness": {"kx": 1, "ky": 1, "kz": 1},
                           "tip_force": [2.0, 0.0, 0.0]})
    ax = plot_backbone(sol, label="bent")
    assert ax.name == "3d" and matplotlib.get_backend() == backend
    # A second backbone on the same axes: the scales grow to cover both, equally.
    longer = softspine.solve({"length": 2.0, "stiffness": {"kx": 1, "ky": 1, "kz": 1}})
    assert plot_backbone(longer, ax) is ax
    limits = np.array([ax.get_xlim(), ax.get_ylim(), ax.get_zlim()])
    assert np.allclose(np.diff(limits, axis=1), np.diff(limits, axis=1)[0])
    assert limits[2, 0] <= 0.0 and limits[2, 1] >= 2.0
    assert [line.get_label() for line in ax.get_lines()][0] == "bent"
    plt.close(ax.figure)


def test_the_cli_plots_without_pyplot(tmp_path):
    """The demo writes its PNG from a bare Figure: pyplot is never imported."""
    code = (
        "import sys; from softspine.cli import main; "
        f"rc = main(['demo', '--out', r'{tmp_path / 'demo.png'}']); "
        "assert 'matplotlib.pyplot' not in sys.modules; sys.exit(rc)"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=300)
    assert done.returncode == 0, done.stderr
    assert (tmp_path / "demo.png").stat().st_size > 10_000


def test_every_installed_module_imports_with_numpy_alone():
    """The wheel's dependencies are NumPy and tqdm only: no module of the package may
    need SciPy or matplotlib to import (the references live in tools/)."""
    code = (
        "import sys, pkgutil, importlib; "
        "sys.modules['scipy'] = None; sys.modules['matplotlib'] = None; "
        "import softspine; "
        "names = [m.name for m in pkgutil.walk_packages(softspine.__path__, 'softspine.')]; "
        "[importlib.import_module(n) for n in names if not n.endswith('__main__')]; "
        "print(len(names))"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=120)
    assert done.returncode == 0, done.stderr
    assert int(done.stdout) >= 6
