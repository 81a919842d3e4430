"""Run code in a fresh interpreter, so that an input which could kill the
process (an abort, a segfault, a hang) fails one test instead of the suite."""

from __future__ import annotations

import subprocess
import sys
import textwrap


def run_isolated(code: str, timeout: float = 120) -> subprocess.CompletedProcess[str]:
    """The finished interpreter (``returncode``, ``stdout``, ``stderr``) that
    ran ``code`` (dedented); a hang past ``timeout`` seconds raises
    ``subprocess.TimeoutExpired``."""
    return subprocess.run(
        [sys.executable, "-c", textwrap.dedent(code)],
        capture_output=True,
        text=True,
        timeout=timeout,
    )
