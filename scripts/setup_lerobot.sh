#!/usr/bin/env bash
# A separate virtual environment for LeRobot's standalone dataset library (import `ledataset`),
# used by tests/test_export_lerobot.py to load `echo-data export --format lerobot` output as a
# LeRobot user would. Separate because its pins clash with ours: lerobot-dataset 0.4.x wants
# datasets<4.2 and huggingface-hub<0.36 (we use datasets 5.x) and resolves numpy 2 / pyarrow 26
# (we pin numpy<2, pyarrow<26). torch==2.13.0 resolves to the CPU wheel, as in our own extras.
set -euo pipefail
cd "$(dirname "$0")/.."
VENV=${ECHO_LEROBOT_VENV:-.venv-lerobot}
if [ ! -x "$VENV/bin/python" ] || ! "$VENV/bin/python" -c "import ledataset, torch" 2>/dev/null; then
  python3 -m venv "$VENV"
  "$VENV/bin/pip" install -q --disable-pip-version-check "lerobot-dataset>=0.4,<0.5" "torch==2.13.0"
fi
