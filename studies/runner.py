"""What the study drivers share: the checkout's root, running `echo-data` from it, and the commit
their numbers belong to. A driver puts this folder on `sys.path` and imports it (the drivers are
scripts, run as `python studies/<name>/<driver>.py`, not a package)."""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def cli(*args: str) -> tuple[str, float]:
    """Run `echo-data ARGS` (this checkout), fail loudly; (stdout, wall seconds)."""
    t0 = time.perf_counter()
    r = subprocess.run([sys.executable, "-m", "echo_data.cli", *args], cwd=ROOT, capture_output=True, text=True)
    if r.returncode != 0:
        sys.exit(f"echo-data {' '.join(args)} failed ({r.returncode}):\n{r.stderr[-2000:]}")
    return r.stdout, time.perf_counter() - t0


def commit() -> str:
    """The checkout's commit (+dirty with local changes to tracked files): the numbers belong to
    this code. On a copy without git (a GPU machine), the environment's SANITY_COMMIT (the caller
    names the commit it copied)."""
    try:
        head = subprocess.run(["git", "rev-parse", "HEAD"], cwd=ROOT, capture_output=True, text=True).stdout.strip()
    except OSError:
        head = ""
    if not head:
        return os.environ.get("SANITY_COMMIT", "") or "unknown"
    dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"], cwd=ROOT, capture_output=True, text=True).stdout.strip()
    return head + ("+dirty" if dirty else "")
