"""The LeRobot virtual environment (scripts/setup_lerobot.sh makes it): where its Python lives and
how a test runs a script in it."""

from __future__ import annotations

import os
import subprocess
from pathlib import Path

import pytest

HERE = Path(__file__).resolve().parents[1]  # tests/
VENV_PYTHON = Path(os.environ.get("ECHO_LEROBOT_PYTHON", HERE.parent / ".venv-lerobot" / "bin" / "python"))


def lerobot_env(tmp_path: Path) -> dict[str, str]:
    """The environment of a subprocess in the LeRobot venv: offline, its own caches, none of our paths."""
    if not VENV_PYTHON.is_file():
        if os.environ.get("CI"):
            pytest.fail(f"{VENV_PYTHON} missing: scripts/setup_lerobot.sh makes it")
        pytest.skip(f"no LeRobot environment at {VENV_PYTHON} (bash scripts/setup_lerobot.sh)")
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME")}
    env.update(HF_HUB_OFFLINE="1", HF_DATASETS_OFFLINE="1", HF_HOME=str(tmp_path / "hf"))
    return env


def run_lerobot(args: list[str], tmp_path: Path, cwd: Path | None = None) -> subprocess.CompletedProcess[str]:
    return subprocess.run([str(VENV_PYTHON), *args], capture_output=True, text=True, env=lerobot_env(tmp_path), timeout=300, cwd=cwd)
