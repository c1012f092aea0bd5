#!/usr/bin/env bash
# A separate virtual environment for LeRobot's standalone dataset library (import `ledataset`)
# and `lerobot-doctor`, in which the README's LeRobot example runs and tests/test_export_lerobot.py
# loads `echo-data export --format lerobot` output as a LeRobot user would. Separate because its
# pins clash with ours: lerobot-dataset 0.4.x wants datasets<4.2 and huggingface-hub<0.36 (we use
# datasets 5.x) and resolves numpy 2 / pyarrow 26 (we pin numpy<2, pyarrow<26). torch==2.13.0
# resolves to the CPU wheel, as in our own extras.
#
# torchvision: the registry's wheels (0.28.0 for torch 2.13.0) and torchcodec's are CUDA builds
# that do not import beside the CPU torch wheel. When `import torchvision` fails, this installs
# scripts/lerobot_env/torchvision: a CPU stand-in with the three pieces ledataset calls
# (transforms.ToTensor, set_video_backend, io.VideoReader on PyAV). Rerunning refreshes it.
set -euo pipefail
cd "$(dirname "$0")/.."
VENV=${ECHO_LEROBOT_VENV:-.venv-lerobot}
if [ ! -x "$VENV/bin/python" ] || ! "$VENV/bin/python" -c "import ledataset, torch, lerobot_doctor" 2>/dev/null; then
  python3 -m venv "$VENV"
  "$VENV/bin/pip" install -q --disable-pip-version-check "lerobot-dataset>=0.4,<0.5" "torch==2.13.0" "lerobot-doctor>=0.2,<0.3"
fi
SITE=$("$VENV/bin/python" -c "import sysconfig; print(sysconfig.get_paths()['purelib'])")
if [ -f "$SITE/torchvision/.echo-data-standin" ] || ! "$VENV/bin/python" -c "import torchvision" 2>/dev/null; then
  rm -rf "$SITE/torchvision"
  cp -r scripts/lerobot_env/torchvision "$SITE/torchvision"
  touch "$SITE/torchvision/.echo-data-standin"
fi
"$VENV/bin/python" -c "import ledataset.datasets.lerobot_dataset, torchvision; print('LeRobot environment ready:', torchvision.__version__)"
