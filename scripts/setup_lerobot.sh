#!/usr/bin/env bash
# The LeRobot environment: a separate virtual environment at .venv-lerobot in the repository root
# (or $ECHO_LEROBOT_VENV) holding LeRobot's standalone dataset library (import `ledataset`),
# `lerobot-doctor` and LeRobot 0.4.4 itself (its ACT and Diffusion policies), in which the README's
# LeRobot example runs and tests/test_export_lerobot.py loads and trains on
# `echo-data export --format lerobot` output as a LeRobot user would. Run it as
#   bash scripts/setup_lerobot.sh
# and use .venv-lerobot/bin/python. Separate because its pins clash with ours: lerobot-dataset
# 0.4.x wants datasets<4.2 and huggingface-hub<0.36 (we use datasets 5.x) and resolves numpy 2 /
# pyarrow 26 (we pin numpy<2, pyarrow<26). torch==2.13.0 resolves to the CPU wheel, as in our extras.
#
# lerobot 0.4.4 declares torch<2.11 and torchvision<0.26, whose wheels are not built for our
# torch 2.13 CPU wheel, and a long list of hardware extras (cameras, motors, wandb, rerun): it is
# installed without its dependencies, then with the ones its policy, dataset and processor
# modules import, each pinned to what the venv already holds (a constraints file from `pip
# freeze`, so nothing ledataset needs moves).
#
# torchvision: the registry's 0.28.0 made to import beside the CPU torch wheel, with a PyAV video
# reader for ledataset (scripts/install_cpu_torchvision.sh says how and why).
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/pip_expected.sh
VENV=${ECHO_LEROBOT_VENV:-.venv-lerobot}
PIP=("$VENV/bin/pip" install -q --disable-pip-version-check)
if [ ! -x "$VENV/bin/python" ] || ! "$VENV/bin/python" -c "import ledataset, torch, lerobot_doctor" 2>/dev/null; then
  python3 -m venv "$VENV"
  "${PIP[@]}" "lerobot-dataset>=0.4,<0.5" "torch==2.13.0" "lerobot-doctor>=0.2,<0.3"
fi
bash scripts/install_cpu_torchvision.sh "$VENV/bin/python"
if ! "$VENV/bin/python" -c "import lerobot.policies.act.modeling_act, lerobot.policies.diffusion.modeling_diffusion" 2>/dev/null; then
  CONSTRAINTS=$(mktemp)
  "$VENV/bin/pip" freeze --exclude-editable | grep -v -i -E "^(lerobot|torchvision)==" > "$CONSTRAINTS"
  "${PIP[@]}" --no-deps "lerobot==0.4.4"
  pip_expected "$VENV/bin/python" "lerobot 0.4.4 is installed around its torch<2.11, torchvision<0.26 and hardware pins, above" -- -c "$CONSTRAINTS" "draccus==0.10.0" "einops>=0.8,<0.9" "diffusers>=0.27.2,<0.36" "accelerate>=1.10,<2" \
    "pyserial>=3.5,<4" "gymnasium>=1.1.1,<2" "termcolor>=2.4,<4" "setuptools>=71,<81"
  rm -f "$CONSTRAINTS"
fi
"$VENV/bin/python" -c "import ledataset.datasets.lerobot_dataset, torchvision, lerobot.policies.act.modeling_act, lerobot.policies.diffusion.modeling_diffusion; print('LeRobot environment ready at $VENV: torchvision', torchvision.__version__)"
