"""`echo-data doctor`: can this machine run the pipeline? Versions, rendering device, a test picture.

The render probe runs in a child process because a missing Vulkan driver can abort the
interpreter inside SAPIEN rather than raise.
"""

from __future__ import annotations

import importlib
import json
import subprocess
import sys
from dataclasses import dataclass, field

PACKAGES = ("numpy", "sapien", "pyroomacoustics", "librosa", "soundfile", "pyarrow", "scipy", "typer", "pydantic")
OPTIONAL = ("torch", "datasets", "ray", "mplib")

FIX = (
    "SAPIEN found no usable Vulkan device. On Debian bookworm run `bash scripts/setup_system.sh` as root "
    "(installs Mesa >= 23 lavapipe from bookworm-backports), or set "
    "VK_ICD_FILENAMES=/usr/share/vulkan/icd.d/lvp_icd.json; on an NVIDIA machine install the Vulkan loader "
    "(libvulkan1) and name the driver's ICD file (nvidia_icd.json) in VK_ICD_FILENAMES."
)
# Why the loader is looked for on its own: without a system libvulkan SAPIEN falls back to a loader of
# its own, which found no device on an NVIDIA H200 machine whose driver ICD was present (2026-11-27);
# with libvulkan1 unpacked there, the same SAPIEN listed the GPU.
NO_LOADER = "no Vulkan loader (libvulkan.so.1) on this machine: apt-get install libvulkan1 (SAPIEN's own fallback loader may find no device)"


def vulkan_loader() -> str | None:
    """The system Vulkan loader's file name, or None where there is none."""
    import ctypes.util

    return ctypes.util.find_library("vulkan")

_PROBE = r"""
import json, sapien, numpy as np
summary = sapien.render.get_device_summary()
scene = sapien.Scene()
b = scene.create_actor_builder(); b.add_box_visual(half_size=[0.2, 0.2, 0.2]); a = b.build_static()
a.set_pose(sapien.Pose([1.0, 0, 0]))
scene.set_ambient_light([0.5, 0.5, 0.5])
cam = scene.add_camera("probe", 32, 32, 1.0, 0.01, 10.0)
scene.update_render(); cam.take_picture()
rgb = cam.get_picture("Color")
print(json.dumps({"summary": summary, "picture_mean": float(np.asarray(rgb)[..., :3].mean())}))
"""


@dataclass
class DoctorReport:
    versions: dict[str, str] = field(default_factory=dict)
    optional: dict[str, str] = field(default_factory=dict)
    device: str = ""
    render_ok: bool = False
    problems: list[str] = field(default_factory=list)


def _version(name: str) -> str:
    try:
        mod = importlib.import_module(name)
    except Exception as e:  # an import that crashes is as missing as one that is absent
        return f"missing ({e.__class__.__name__})"
    return str(getattr(mod, "__version__", "installed"))


def run_doctor(timeout: float = 120.0) -> DoctorReport:
    """Collect versions and probe rendering; problems come with the fix."""
    rep = DoctorReport()
    for p in PACKAGES:
        rep.versions[p] = _version(p)
        if rep.versions[p].startswith("missing"):
            rep.problems.append(f"{p} is not importable: run `bash scripts/setup.sh`")
    for p in OPTIONAL:
        rep.optional[p] = _version(p)
    np_ver = rep.versions.get("numpy", "")
    planning = rep.optional.get("mplib", "missing")
    if np_ver and np_ver[0].isdigit() and int(np_ver.split(".")[0]) >= 2 and not planning.startswith("missing"):
        rep.problems.append("numpy >= 2 is installed beside mplib (the `planning` extra), which crashes under it; pip install 'numpy<2'")
    try:
        out = subprocess.run([sys.executable, "-c", _PROBE], capture_output=True, text=True, timeout=timeout)
    except subprocess.TimeoutExpired:
        rep.problems.append("the render probe timed out. " + FIX)
        return rep
    lines = [ln for ln in out.stdout.splitlines() if ln.startswith("{")]
    if out.returncode == 0 and lines:
        res = json.loads(lines[-1])
        first = res["summary"].strip().splitlines()
        rep.device = first[0] if first else "unknown"
        rep.render_ok = True
    else:
        tail = (out.stderr or out.stdout).strip().splitlines()[-1:] or ["no output"]
        rep.problems.append(f"rendering failed ({tail[0][:200]}). " + FIX)
        if vulkan_loader() is None:  # the likely cause; a machine where SAPIEN's own loader renders is fine
            rep.problems.append(NO_LOADER)
    return rep
