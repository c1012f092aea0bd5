#!/usr/bin/env bash
# One-command setup on a fresh Debian bookworm machine (as root): system packages
# (Mesa 25 lavapipe for CPU rendering) and echo-data with its test extras.
set -euo pipefail
cd "$(dirname "$0")/.."
if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null; then bash scripts/setup_system.sh; fi
python3 -m pip install -q --disable-pip-version-check -e '.[test,docs]'   # docs: the site .ci/run builds
# robomimic's SequenceDataset reads `export --format robomimic` in the tests; its declared deps
# (a CUDA torchvision, egl_probe) do not install beside the CPU torch: see pyproject.toml.
python3 -m pip install -q --disable-pip-version-check --no-deps "robomimic==0.3.0"
# robomimic's train.py (tests/robomimic_train.py) imports psutil and imageio, and its encoders torchvision.
source scripts/pip_expected.sh
pip_expected python3 "robomimic is installed without its declared dependencies, which pull a CUDA torchvision; those it runs on are installed here" -- \
  "psutil>=5" "imageio>=2.30,<3"
# torchvision runs on torch, which the test extra installs below Python 3.12 only (pyproject.toml).
if python3 -c 'import sys; sys.exit(sys.version_info >= (3, 12))'; then
  bash scripts/install_cpu_torchvision.sh "$(command -v python3)"
fi
# HF datasets decodes its Audio feature (the cards' `audio` config) with torchcodec, which loads the
# system FFmpeg 5.1 libraries (scripts/setup_system.sh). 0.13.0 is the wheel measured to import
# beside the CPU torch 2.13.0 and decode the dataset's WAVs; later ones link CUDA libraries.
if python3 -c 'import sys; sys.exit(sys.version_info >= (3, 12))'; then
  python3 -m pip install -q --disable-pip-version-check --no-deps "torchcodec==0.13.0"
fi
# LeRobot's dataset library in its own environment (its pins clash with ours); used by tests.
bash scripts/setup_lerobot.sh
