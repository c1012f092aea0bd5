"""A CPU stand-in for torchvision in the LeRobot environment that scripts/setup_lerobot.sh makes.

The registry's torchvision wheels (0.28.0 is the one built for torch 2.13.0) are CUDA builds whose
`_C` extension links libtorch_cuda / libc10_cuda, absent beside the CPU torch wheel, so `import
torchvision` fails ("operator torchvision::nms does not exist"); torchcodec's wheels link the same
CUDA libraries. `ledataset` (LeRobot's dataset library) imports torchvision at module level and,
to read image and video features, calls only `transforms.ToTensor`, `set_video_backend` and
`io.VideoReader` (its "pyav" backend). This package provides exactly those, with torchvision's
documented semantics, on PyAV (which ledataset already depends on); setup_lerobot.sh installs it
only when the real torchvision does not import.
"""

from . import io, transforms  # noqa: F401

__version__ = "0.0+echo-data-cpu-standin"
_backend = "pyav"


def set_video_backend(backend: str) -> None:
    """torchvision.set_video_backend: only "pyav" exists here."""
    global _backend
    if backend != "pyav":
        raise ValueError(f"video backend {backend!r} is not available in the echo-data stand-in (use 'pyav')")
    _backend = backend


def get_video_backend() -> str:
    return _backend
