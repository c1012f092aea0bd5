"""Apartment generation, stage 3 (pure): rugs on the floor and curtains in front of walls, the
soft furnishings the cameras see and the acoustics absorb with.
"""

from __future__ import annotations

import math

import numpy as np

from echo_data.floorplan import (
    Doorway,
    Furnishing,
    Furniture,
    Rect,
    Room,
)
from echo_data.scene.furniture import _inner
from echo_data.scene.structure import _EPS, DOOR_CLEARANCE_SIDE, _Piece, _r2, _rect_uv

# --- soft furnishings (acoustic absorbers; the visual and the acoustic scene share them) ---
# Absorption coefficients are pyroomacoustics' database entries (tabulated from Vorländer,
# "Auralization", appendix).
RUG_MATERIALS = ("carpet_tufted_9m", "carpet_1.35_kg_m2", "carpet_hairy", "carpet_6mm_open_cell_foam")
CURTAIN_MATERIALS = ("curtains_cotton_0.5", "curtains_densely_woven", "curtains_fabric", "curtains_velvet")
RUG_ROOMS = ("living", "bedroom", "study", "hall")
FITTED_CARPETS = ("carpet_cotton", "carpet_tufted_9.5mm", "carpet_1.35_kg_m2", "carpet_tufted_9m")  # no rug on these
CURTAIN_ROOMS = ("living", "bedroom", "study")
RUG_COVER = (0.4, 0.7)  # share of a room's floor under a rug
CURTAIN_WIDTH = (1.4, 2.6)  # m, a window's pair of curtains drawn open at its sides
MIN_CURTAIN_WIDTH = 1.0  # m, narrower free wall gets no window
CURTAIN_OFF_WALL = 0.002  # m, gap between wall face and curtain ...
CURTAIN_DEPTH = 0.015  # m, ... so furniture (WALL_GAP off the wall) may stand in front of it
CURTAIN_TOP_BELOW_CEILING = 0.1
SECOND_WINDOW_PROBABILITY = 0.7

def _furnish(
    rooms: list[Room],
    pieces: list[_Piece],
    doorways: list[Doorway],
    furniture: list[Furniture],
    t: float,
    wall_height: float,
    rng: np.random.Generator,
) -> tuple[Furnishing, ...]:
    """Rugs on floors without a fitted carpet in living rooms, bedrooms, studies and halls; curtains at one or two
    windows on the exterior walls of living rooms, bedrooms and studies (away from doorways;
    furniture may stand in front of them).
    Kitchens and bathrooms stay hard. Drawn from their own generator (`rng`) so adding them
    leaves every other draw of the plan as it was."""
    out: list[Furnishing] = []
    for room in rooms:
        inner = _inner(room, t)
        if room.kind in RUG_ROOMS and room.floor_material not in FITTED_CARPETS:
            share = rng.uniform(*RUG_COVER)
            k = math.sqrt(share)
            w, h = (inner.xmax - inner.xmin) * k, (inner.ymax - inner.ymin) * k
            cx = inner.center[0] + rng.uniform(-0.5, 0.5) * (inner.xmax - inner.xmin - w)
            cy = inner.center[1] + rng.uniform(-0.5, 0.5) * (inner.ymax - inner.ymin - h)
            fp = Rect(_r2(cx - w / 2), _r2(cy - h / 2), _r2(cx + w / 2), _r2(cy + h / 2))
            out.append(Furnishing(len(out), "rug", room.index, fp, (0.0, 0.01), str(rng.choice(RUG_MATERIALS))))
        if room.kind not in CURTAIN_ROOMS:
            continue
        walls = sorted((p for p in pieces if p.exterior and room.index in p.rooms), key=lambda p: -p.length)
        for n, p in enumerate(walls[:2]):
            if n == 1 and rng.random() >= SECOND_WINDOW_PROBABILITY:
                break
            below = p.rooms[0] == room.index  # the room lies on the low side of the wall line
            face = p.coord - t / 2.0 if below else p.coord + t / 2.0
            sgn = -1.0 if below else 1.0  # from the wall into the room
            lo, hi = p.lo + t / 2.0 + 0.05, p.hi - t / 2.0 - 0.05
            blocked = [
                (c - dw.width / 2.0 - DOOR_CLEARANCE_SIDE, c + dw.width / 2.0 + DOOR_CLEARANCE_SIDE)
                for dw in doorways
                if dw.axis == p.axis and abs((dw.center[1] if p.axis == "x" else dw.center[0]) - p.coord) < _EPS
                for c in [dw.center[0] if p.axis == "x" else dw.center[1]]
            ]
            free = [(lo, hi)]
            for b0, b1 in blocked:
                free = [seg for f0, f1 in free for seg in ((f0, min(f1, b0)), (max(f0, b1), f1)) if seg[1] - seg[0] > 0.0]
            free = [seg for seg in free if seg[1] - seg[0] >= MIN_CURTAIN_WIDTH]
            if not free:
                continue
            f0, f1 = free[int(rng.integers(len(free)))]
            w = min(rng.uniform(*CURTAIN_WIDTH), f1 - f0)
            u0 = rng.uniform(f0, f1 - w)
            v0, v1 = face + sgn * CURTAIN_OFF_WALL, face + sgn * (CURTAIN_OFF_WALL + CURTAIN_DEPTH)
            fp = _rect_uv(p.axis, _r2(u0), _r2(u0 + w), round(v0, 3), round(v1, 3))
            if not any(fp.intersects(f.footprint) for f in furniture):
                z = (0.05, wall_height - CURTAIN_TOP_BELOW_CEILING)
                out.append(Furnishing(len(out), "curtain", room.index, fp, z, str(rng.choice(CURTAIN_MATERIALS))))
    return tuple(out)
