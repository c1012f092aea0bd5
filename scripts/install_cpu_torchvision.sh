#!/usr/bin/env bash
# Installs the registry's torchvision 0.28.0 (the release for torch 2.13) into the environment of
# the Python given as $1, made to import beside the CPU torch wheel, with a PyAV video reader.
#
# That wheel is a CUDA build. Its Python part (models, transforms, ops.misc: all that LeRobot's
# ACT/Diffusion and robomimic's encoders use) runs on CPU; only its compiled ops (_C.so, linked
# to libtorch_cuda) cannot load. torchvision copes with that (`extension._has_ops()` is then
# False) except in two fake-kernel registrations (nms, qnms) that raise "operator
# torchvision::nms does not exist" at import: they are guarded on `_has_ops()` here. torchvision
# 0.26+ also has no video decoder (moved to torchcodec, whose wheels are CUDA builds as well),
# while ledataset 0.4.4 decodes video through `torchvision.io.VideoReader` (its "pyav" backend):
# scripts/lerobot_env/torchvision/io.py (that reader on PyAV) is added as
# `torchvision.io.VideoReader` where it is missing. Idempotent: a marker file records the patch.
set -euo pipefail
cd "$(dirname "$0")/.."
PY=$1
TV=$("$PY" -c "import sysconfig; print(sysconfig.get_paths()['purelib'])")/torchvision
if [ -f "$TV/.echo-data-cpu" ] && "$PY" -c "import torchvision.models, torchvision.io; torchvision.io.VideoReader" 2>/dev/null; then
  exit 0
fi
rm -rf "$TV"  # an earlier stand-in, or a torchvision that does not import
"$PY" -m pip install -q --disable-pip-version-check --no-deps --force-reinstall "torchvision==0.28.0"
sed -i -E 's|^@torch\.library\.register_fake\("torchvision::(\w+)"\)$|@(torch.library.register_fake("torchvision::\1") if torchvision.extension._has_ops() else (lambda fn: fn))|' "$TV/_meta_registrations.py"
cp scripts/lerobot_env/torchvision/io.py "$TV/io/_echo_pyav_reader.py"
printf '\nif "VideoReader" not in globals():  # echo-data: torchvision >= 0.26 has no video decoder\n    from ._echo_pyav_reader import VideoReader\n' >> "$TV/io/__init__.py"
touch "$TV/.echo-data-cpu"
"$PY" -c "import torchvision.models, torchvision.io; torchvision.io.VideoReader"
