"""Pinhole camera geometry shared by the robot, the dataset metadata and the loaders.

Conventions (one owner): pixel (u, v) has its centre at (u + 0.5, v + 0.5); K maps OpenCV
camera coordinates (x right, y down, z forward) to pixels; depth images hold z (distance along
the optical axis) in millimetres, 0 where nothing was hit; poses are 4x4 camera-to-world
matrices in those OpenCV axes. SAPIEN's camera entity frame is x forward, y left, z up.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

DEPTH_UNIT_M = 0.001  # depth images store millimetres

# Columns of the OpenCV axes expressed in SAPIEN's camera frame: x_cv = -y_s, y_cv = -z_s, z_cv = x_s.
_SAPIEN_FROM_CV = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])


def intrinsics(width: int, height: int, fov_y_deg: float) -> np.ndarray:
    """3x3 K of a camera with square pixels and the principal point at the image centre
    (how the robot mounts its cameras: vertical field of view given, horizontal derived)."""
    fy = (height / 2.0) / math.tan(math.radians(fov_y_deg) / 2.0)
    return np.array([[fy, 0.0, width / 2.0], [0.0, fy, height / 2.0], [0.0, 0.0, 1.0]])


def camera_info(cam: Any) -> dict[str, Any]:
    """What a user needs to lift a depth image (from a recipe `CameraConfig`)."""
    return {
        "width": cam.width,
        "height": cam.height,
        "fov_y_deg": cam.fov_deg,
        "K": intrinsics(cam.width, cam.height, cam.fov_deg).tolist(),
        "depth_unit_m": DEPTH_UNIT_M,
        "axes": "OpenCV: x right, y down, z forward; pixel centres at (u + 0.5, v + 0.5)",
    }


def cv_pose(sapien_matrix: np.ndarray) -> np.ndarray:
    """SAPIEN camera entity pose (4x4, x forward) -> camera-to-world in OpenCV axes (4x4)."""
    m = np.array(sapien_matrix, dtype=np.float64)
    out = m.copy()
    out[:3, :3] = m[:3, :3] @ _SAPIEN_FROM_CV
    return out


def depth_to_world(depth: np.ndarray, K: np.ndarray, cam2world: np.ndarray, unit_m: float = DEPTH_UNIT_M) -> np.ndarray:
    """Depth image (H, W) -> (H, W, 3) world points (NaN where depth is 0: nothing hit).

    `cam2world` may be the flat 16-vector of a `camera_pose.*` column."""
    d = np.asarray(depth, dtype=np.float64) * unit_m
    h, w = d.shape
    T = np.asarray(cam2world, dtype=np.float64).reshape(4, 4)
    K = np.asarray(K, dtype=np.float64)
    u, v = np.meshgrid(np.arange(w) + 0.5, np.arange(h) + 0.5)
    x = (u - K[0, 2]) / K[0, 0] * d
    y = (v - K[1, 2]) / K[1, 1] * d
    pts = np.stack([x, y, d], axis=-1) @ T[:3, :3].T + T[:3, 3]
    pts[d <= 0] = np.nan
    return pts
