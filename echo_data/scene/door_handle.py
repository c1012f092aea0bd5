"""Where a door's pull handle is: the one owner of the handle layout.

A vertical bar on two standoff posts on both faces of the leaf, near its free edge; a parallel
gripper with horizontal fingers grasps it from the front. Pure geometry (numpy, no SAPIEN), so
the door builder (`echo_data.scene.articulated`), the navigation grid (`echo_data.scene.nav`,
which keeps the bars out of the base's way) and the OpenDoor expert all read the same numbers.
"""

from __future__ import annotations

import math

import numpy as np

from echo_data.floorplan import Door

HANDLE_EDGE_OFFSET = 0.08  # m from the free edge to the bar's axis
HANDLE_STANDOFF = 0.06  # m from the leaf face to the bar's axis
HANDLE_BAR = (0.024, 0.024, 0.18)  # bar size (along leaf, along normal, height), m
HANDLE_POST = 0.016  # standoff post cross-section, m


def door_handle_local(door: Door, face: float = 1.0) -> np.ndarray:
    """Centre of the handle bar in the leaf frame (x hinge→free edge, y leaf normal, z up).

    `face` = +1 is the face the leaf's +y normal points to (the side the door opens towards
    when `open_sign` = +1), -1 the other face.
    """
    return np.array(
        [door.width - HANDLE_EDGE_OFFSET, face * (door.thickness / 2.0 + HANDLE_STANDOFF), door.handle_height]
    )


def door_handle_world(door: Door, q: float, face: float = 1.0) -> np.ndarray:
    """World position of a handle bar's centre at hinge angle q."""
    local = door_handle_local(door, face)
    yaw = door.leaf_yaw(q)
    c, s = math.cos(yaw), math.sin(yaw)
    return np.array(
        [door.hinge[0] + c * local[0] - s * local[1], door.hinge[1] + s * local[0] + c * local[1], local[2]]
    )


def handle_xy(door: Door, q: float, face: float | None = None) -> tuple[float, float]:
    """Plan position of a door's handle bar at hinge angle q.

    `face` +1 is the leaf's +y normal side, -1 the other; default: the swing side
    (`open_sign`), i.e. the handle a robot standing where the leaf opens to pulls.
    """
    p = door_handle_world(door, q, door.open_sign if face is None else face)
    return (float(p[0]), float(p[1]))
