"""The ``arduinobot`` command as a user types it: this checkout's CLI in a subprocess of
the test's interpreter, from the repository root."""

from __future__ import annotations

import subprocess
import sys

from .procs import REPO


def run_cli(*args: str, env: dict[str, str] | None = None,
            timeout: float = 900) -> subprocess.CompletedProcess[str]:
    """``arduinobot ARGS...``; its exit code, stdout and stderr (text). ``env`` replaces the
    environment (None: the test's); ``timeout`` [s] is a net against a hang, not a bound
    the test asserts (a long motion executes for ~20 s on a loaded machine)."""
    return subprocess.run([sys.executable, "-m", "arduinobot.cli.main", *args],
                          capture_output=True, text=True, cwd=REPO, env=env, timeout=timeout)
