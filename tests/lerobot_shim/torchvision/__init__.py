"""A stand-in for torchvision inside the LeRobot test environment (tests/test_export_lerobot.py).

The registry's torchvision wheels are CUDA builds that fail to import beside the CPU torch
wheel ("operator torchvision::nms does not exist"). `ledataset` imports torchvision at module
level but, for image features read from Parquet, calls only `transforms.ToTensor`; video
decoding (`torchvision.io`) is never reached because the export stores no videos. This package
provides exactly that transform, with torchvision's documented semantics.
"""

from . import transforms  # noqa: F401

__version__ = "0.0+echo-data-test-shim"
