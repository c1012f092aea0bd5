"""Where the LeRobot virtual environment's Python lives (scripts/setup_lerobot.sh makes it)."""

from __future__ import annotations

import os
from pathlib import Path

HERE = Path(__file__).resolve().parents[1]  # tests/
VENV_PYTHON = Path(os.environ.get("ECHO_LEROBOT_PYTHON", HERE.parent / ".venv-lerobot" / "bin" / "python"))
