"""Hand-built floor plans for the acoustic-scene tests (no generator needed), plus sanity
checks of the plans themselves."""

from __future__ import annotations

import math

import numpy as np
from scipy import signal

from echo_data.floorplan import Door, Doorway, FloorPlan, Furniture, Rect, Room, WallSegment

FS = 16000  # sample rate of the responses band_t30 reads
T = 0.1  # wall thickness
H = 2.5  # ceiling height
DOOR_W = 1.0
DOOR_H = 2.1


def row_plan(
    widths: tuple[float, ...] = (4.0, 4.0, 4.0),
    depth: float = 4.0,
    doorway_y: tuple[float, ...] | None = None,
    door: bool = False,
    wall: str = "plasterboard",
    floor: str = "linoleum_on_concrete",
    ceiling: str = "ceiling_plasterboard",
    furniture: tuple[Furniture, ...] = (),
    seed: int = 7,
) -> FloorPlan:
    """Rooms in a row along +x (room i spans [x_i, x_i+1] × [0, depth]); a 1 m doorway in each
    interior wall at height y = doorway_y[i]; `door` hangs a (closed) leaf in doorway 0 that
    swings into room 1."""
    xs = [0.0]
    for w in widths:
        xs.append(xs[-1] + w)
    n = len(widths)
    doorway_y = doorway_y if doorway_y is not None else tuple(depth - 1.0 for _ in range(n - 1))
    rooms = tuple(
        Room(i, "living", Rect(xs[i], 0.0, xs[i + 1], depth), floor, wall, ceiling) for i in range(n)
    )
    walls = [
        WallSegment((-T / 2, 0.0), (xs[-1] + T / 2, 0.0), T, H, wall, True),
        WallSegment((-T / 2, depth), (xs[-1] + T / 2, depth), T, H, wall, True),
        WallSegment((0.0, 0.0), (0.0, depth), T, H, wall, True),
        WallSegment((xs[-1], 0.0), (xs[-1], depth), T, H, wall, True),
    ]
    doorways = []
    for i in range(1, n):
        y = doorway_y[i - 1]
        walls.append(WallSegment((xs[i], 0.0), (xs[i], y - DOOR_W / 2), T, H, wall, False))
        walls.append(WallSegment((xs[i], y + DOOR_W / 2), (xs[i], depth), T, H, wall, False))
        doorways.append(Doorway(i - 1, (xs[i], y), "y", DOOR_W, DOOR_H, (i - 1, i)))
    doors = ()
    if door and n > 1:
        xc, y = xs[1], doorway_y[0]
        doors = (
            Door(
                index=0,
                doorway=0,
                hinge=(xc + T / 2 + 0.012 + 0.02, y - DOOR_W / 2 - 0.02),
                closed_yaw=math.pi / 2,
                open_sign=-1.0,  # clockwise: the free edge swings towards +x, into room 1
                width=DOOR_W + 0.04,
                thickness=0.04,
                height=DOOR_H - 0.02,
                max_angle=math.radians(105),
                open_threshold=math.radians(60),
                angle=0.0,
                handle_height=1.0,
                swing_room=1,
                material="wooden_door",
            ),
        )
    return FloorPlan(7 if seed is None else seed, rooms, tuple(walls), tuple(doorways), doors, tuple(furniture), (), (), H)


def shoebox_plan(sx: float, sy: float, wall: str, floor: str, ceiling: str, seed: int = 3) -> FloorPlan:
    """One closed rectangular room (inner size sx × sy × H)."""
    return row_plan((sx + T,), sy + T, wall=wall, floor=floor, ceiling=ceiling, seed=seed)


def band_t30(h: np.ndarray, fc: float) -> float:
    """T30 of an octave band from the Schroeder integral (-5 … -35 dB, extrapolated to 60 dB)."""
    sos = signal.butter(3, [fc / np.sqrt(2), min(fc * np.sqrt(2), 0.45 * FS)], btype="band", fs=FS, output="sos")
    x = signal.sosfiltfilt(sos, h.astype(np.float64))
    edc = np.cumsum((x**2)[::-1])[::-1]
    edc_db = 10 * np.log10(edc / edc[0] + 1e-30)
    i5, i35 = int(np.argmax(edc_db <= -5)), int(np.argmax(edc_db <= -35))
    assert i35 > i5 > 0
    t = np.arange(len(x)) / FS
    slope = np.polyfit(t[i5:i35], edc_db[i5:i35], 1)[0]
    return -60.0 / slope
