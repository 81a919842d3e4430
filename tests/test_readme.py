"""Issue 11, item 3: every Python block of the README runs, in order, in one
fresh interpreter (they build on each other, as a reader types them); the
guide's too (issue 29, item 7). The Rust block is a doctest (``cargo test
--doc``, see ``src/lib.rs``)."""

from __future__ import annotations

import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

README = Path(__file__).resolve().parent.parent / "README.md"
GUIDE = README.parent / "docs" / "guide.md"
REFERENCE = README.parent / "docs" / "reference.md"


def python_blocks(text):
    return re.findall(r"^```python\n(.*?)^```", text, flags=re.S | re.M)


def test_the_readme_has_python_blocks():
    assert len(python_blocks(README.read_text())) >= 2


@pytest.mark.slow
@pytest.mark.parametrize("page", [README, GUIDE, REFERENCE], ids=["readme", "guide", "reference"])
def test_the_python_blocks_run(tmp_path, page):
    # As a reader runs them from the repository's root, with its example files
    # (in a copy: the blocks write files).
    shutil.copytree(README.parent / "examples", tmp_path / "examples")
    script = "\n\n".join(python_blocks(page.read_text()))
    run = subprocess.run(
        [sys.executable, "-c", script],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=300,
        env={"MPLBACKEND": "Agg", "PATH": "/usr/bin:/bin"},
    )
    assert run.returncode == 0, run.stderr[-3000:]
