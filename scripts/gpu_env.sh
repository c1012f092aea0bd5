# Sourced by scripts/gpu_bench.sh and scripts/gpu_sanity.sh: the environment of the NVIDIA GPU
# machine without a package registry (Python 3.12 image; docs/vector_envs.md). From the checkout's root:
# - the bundle of the packages that image lacks (git-ignored .gpu_bundle/site312.tar.xz), unpacked
#   once into $GS and put first on PYTHONPATH with the checkout and benchmarks/;
# - the Vulkan loader: the image has none, and SAPIEN's own fallback then finds no rendering device
#   (seen on an H200, 2026-11-27); the one carried as Debian packages in the git-ignored .gl/
#   (`apt-get download libvulkan1 libegl1 libglvnd0 libopengl0 libgl1 libglx0 libgles2` where a
#   package source is reachable) is unpacked, as root;
# - the NVIDIA driver's Vulkan ICD named for SAPIEN; one lavapipe thread; $PY.
GS=${GS:-/tmp/gs}
if [ -f .gpu_bundle/site312.tar.xz ] && [ ! -f "$GS/.unpacked" ]; then
  rm -rf "$GS" && mkdir -p "$GS" && tar -xJf .gpu_bundle/site312.tar.xz -C "$GS" && touch "$GS/.unpacked" || echo "BUNDLE UNPACK FAILED"
fi
export PYTHONPATH=$GS/site:$PWD:$PWD/benchmarks
# The NVIDIA ICD (libGLX_nvidia) also needs glvnd's dispatch library: without it the loader finds
# "no drivers" and SAPIEN "no rendering device" (seen on an H200 whose image had libvulkan alone).
# .gl/ holds: libvulkan1 libegl1 libglvnd0 libopengl0 libgl1 libglx0 libgles2.
if ! ldconfig -p | grep -q libGLdispatch && ls .gl/*.deb >/dev/null 2>&1; then
  for f in .gl/*.deb; do dpkg -x "$f" /; done; ldconfig
fi
J=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
[ -f "$J" ] && export VK_ICD_FILENAMES=$J VK_DRIVER_FILES=$J
E=/usr/local/nvidia/share/glvnd/egl_vendor.d/10_nvidia.json
[ -f "$E" ] && export __EGL_VENDOR_LIBRARY_FILENAMES=$E
export LP_NUM_THREADS=1 PYTHONDONTWRITEBYTECODE=1
PY=${PY:-python3}
