"""Hand-made floor plans for the navigation tests (no generator needed).

Two rooms side by side, [0,4]x[0,4] and [4,8]x[0,4], joined by a 1 m doorway in the wall x=4
at y in [1.5, 2.5] that holds a hinged door swinging into room 1; a table with a phone in
room 0 (front facing south) and a sink cabinet with a faucet in room 1 (front facing west).
"""

from __future__ import annotations

import math

from echo_data.floorplan import (
    Door,
    Doorway,
    Faucet,
    FloorPlan,
    Furniture,
    PlacedObject,
    Rect,
    Room,
    WallSegment,
)

T = 0.1  # wall thickness


def _wall(a: tuple[float, float], b: tuple[float, float], exterior: bool) -> WallSegment:
    return WallSegment(a=a, b=b, thickness=T, height=2.5, material="plasterboard", exterior=exterior)


def two_room_plan(door_angle: float = 0.0) -> FloorPlan:
    """The two-room plan with the door at `door_angle` (0 = closed)."""
    rooms = (
        Room(0, "living", Rect(0.0, 0.0, 4.0, 4.0), "carpet_cotton", "plasterboard", "ceiling_plasterboard"),
        Room(1, "kitchen", Rect(4.0, 0.0, 8.0, 4.0), "linoleum_on_concrete", "plasterboard", "ceiling_plasterboard"),
    )
    walls = (
        _wall((0.0, 0.0), (8.0, 0.0), True),
        _wall((0.0, 4.0), (8.0, 4.0), True),
        _wall((0.0, 0.0), (0.0, 4.0), True),
        _wall((8.0, 0.0), (8.0, 4.0), True),
        _wall((4.0, 0.0), (4.0, 1.5), False),
        _wall((4.0, 2.5), (4.0, 4.0), False),
    )
    doorways = (Doorway(0, (4.0, 2.0), "y", 1.0, 2.1, (0, 1)),)
    # Hinge at the doorway's south edge, on room 1's wall face; the closed leaf runs north
    # (yaw pi/2); opening turns it clockwise towards east, into room 1.
    doors = (
        Door(
            index=0,
            doorway=0,
            hinge=(4.0 + T / 2 + 0.02, 1.52),
            closed_yaw=math.pi / 2,
            open_sign=-1.0,
            width=0.96,
            thickness=0.04,
            height=2.05,
            max_angle=math.radians(110),
            open_threshold=math.radians(60),
            angle=door_angle,
            handle_height=1.0,
            swing_room=1,
            material="wooden_door",
        ),
    )
    furniture = (
        Furniture(0, "table", 0, (1.5, 3.45), (1.2, 0.7, 0.75), -math.pi / 2, "wooden_door", True),
        Furniture(1, "sink_cabinet", 1, (7.65, 0.9), (0.6, 1.0, 0.9), math.pi, "wooden_door", True),
        Furniture(2, "counter", 1, (6.0, 3.65), (1.4, 0.6, 0.9), math.pi / 2 * -1, "wooden_door", True),
    )
    faucets = (
        Faucet(0, 1, (7.55, 0.9, 1.0), math.pi, 0.15, math.pi / 2, math.radians(5), math.pi / 2, (7.6, 0.9, 1.1)),
    )
    objects = (
        PlacedObject(0, "phone_0", "phone", (1.3, 3.3, 0.76), 0.0, 0, True),
        PlacedObject(1, "mug_0", "mug", (6.2, 3.55, 0.95), 0.0, 2, False),
    )
    return FloorPlan(
        seed=0,
        rooms=rooms,
        walls=walls,
        doorways=doorways,
        doors=doors,
        furniture=furniture,
        faucets=faucets,
        objects=objects,
    )
