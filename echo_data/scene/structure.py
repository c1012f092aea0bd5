"""Apartment generation, stage 1 (pure): room kinds, walls with doorways cut out, wide openings
between the rectangles of one space, doorways and hinged doors with their doorbells.

Called by `echo_data.scene.generate` (the orchestration); later stages (`scene.furniture`,
`scene.soft_furnishings`) keep clear of the doorway zones and door swings drawn here.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from echo_data.floorplan import (
    Door,
    Doorway,
    Rect,
    Room,
    WallSegment,
)
from echo_data.recipe import Recipe
from echo_data.scene.layouts import Layout, opening_span

_EPS = 1e-6


class GenerationError(RuntimeError):
    """The generator could not build a valid apartment within its retry budget."""


@dataclass(frozen=True)
class _Piece:
    """A stretch of wall centre line between two rooms (or a room and outside, -1)."""

    axis: str  # 'x': the wall runs along x at y = coord
    coord: float
    lo: float
    hi: float
    rooms: tuple[int, int]  # (room on the low side, room on the high side)

    @property
    def length(self) -> float:
        return self.hi - self.lo

    @property
    def exterior(self) -> bool:
        return -1 in self.rooms


def _r2(v: float) -> float:
    return round(float(v), 2)


def _xy(axis: str, u: float, v: float) -> tuple[float, float]:
    """Plan point from (along-wall u, across-wall v) for a wall along `axis`."""
    return (u, v) if axis == "x" else (v, u)


def _rect_uv(axis: str, u0: float, u1: float, v0: float, v1: float) -> Rect:
    x0, y0 = _xy(axis, min(u0, u1), min(v0, v1))
    x1, y1 = _xy(axis, max(u0, u1), max(v0, v1))
    return Rect(x0, y0, x1, y1)



ROOM_KINDS = ("living", "kitchen", "bedroom", "bathroom", "hall", "study")

# --- doors -----------------------------------------------------------------------------
DOOR_MAX_ANGLE = math.radians(105.0)
DOOR_OPEN_THRESHOLD = min(math.radians(60.0), 0.7 * DOOR_MAX_ANGLE)
DOOR_THICKNESS = 0.04
DOOR_OVERLAP = 0.02  # leaf overlaps the opening by this much on each side (it hangs on the wall face)
DOOR_FACE_GAP = 0.012  # leaf to wall face when closed (>= 1 cm or the joint jams: docs/SIMULATION_NOTES.md#articulations)
DOOR_HANDLE_HEIGHT = 1.0
DOORWAY_HEIGHT = 2.1
DOORBELL_Z = 1.2
DOORBELL_BESIDE = 0.15  # from the doorway edge, on the latch side
INTERIOR_BELL_PROBABILITY = 0.25
# Doorway edge to the nearest wall corner (inner face): >= 0.3 m by spec, and the leaf at
# max angle reaches width * |cos(max)| ≈ 0.27 m behind its hinge.
DOORWAY_CORNER_MARGIN = 0.45
DOOR_CLEARANCE_DEPTH = 1.2  # free of furniture in front of a doorway, both sides
DOOR_CLEARANCE_SIDE = 0.35  # beyond each doorway edge (covers the leaf behind the hinge)
# A door that gets opened (one with a bell): the OpenDoor expert holds the handle and drives
# its base on a circle about the hinge, ending ≈0.55 m behind the hinge and ≈1 m out; with
# the base radius that needs this much free wall beyond the hinge-side edge and this deep a
# furniture-free area on the swing side.
DOOR_HINGE_SIDE_ROOM = 1.05
DOOR_OPERATION_DEPTH = 1.55

# ------------------------------------------------------------------------------ rooms
def _assign_kinds(rects: list[Rect], rng: np.random.Generator) -> list[str]:
    """Largest room is the living room; always a kitchen; a bathroom in the smallest room from 4 rooms."""
    n = len(rects)
    order = sorted(range(n), key=lambda i: (-rects[i].area, i))
    kinds = [""] * n
    kinds[order[0]] = "living"
    rest = order[1:]
    if n >= 4:
        kinds[rest[-1]] = "bathroom"
        rest = rest[:-1]
    pool = ["kitchen", "bedroom", "study", "hall", "bedroom"][: len(rest)]
    perm = rng.permutation(len(rest))
    for slot, idx in zip(perm, rest):
        kinds[idx] = pool[int(slot)]
    return kinds


def _assign_space_kinds(layout: Layout, rng: np.random.Generator) -> list[str]:
    """Kinds for a layout with fixed kinds (joined spaces, a corridor's hall): the largest free
    space is the living room unless the family made one; a kitchen unless the family made one;
    a bathroom in the smallest free rectangle from 4 spaces; the rest bedrooms, studies (and a
    hall where there is no corridor)."""
    rects = layout.rects
    kinds = [layout.kinds.get(i, "") for i in range(len(rects))]
    free = sorted((i for i in range(len(rects)) if not kinds[i]), key=lambda i: (-rects[i].area, i))
    n_spaces = len(rects) - len(layout.joins)
    if "living" not in kinds and free:
        kinds[free.pop(0)] = "living"
    if n_spaces >= 4 and free:
        kinds[free.pop()] = "bathroom"
    pool = [] if "kitchen" in kinds else ["kitchen"]
    pool += ["bedroom", "study", "bedroom", "study"] if "hall" in kinds else ["bedroom", "study", "hall", "bedroom"]
    pool = pool[: len(free)]
    if "kitchen" not in kinds and "bathroom" not in kinds and "kitchen" not in pool:
        return []  # no room for the sink
    perm = rng.permutation(len(free))
    for slot, idx in zip(perm, free):
        kinds[idx] = pool[int(slot)]
    return kinds


def _wide_openings(layout: Layout, rooms: list[Room], t: float, height: float) -> list[Doorway]:
    """The doorless, floor-to-ceiling openings that join the rectangles of one space."""
    out: list[Doorway] = []
    for a, b in layout.joins:
        axis, c, u, width = opening_span(rooms[a].rect, rooms[b].rect, t)
        lo_side, hi_side = (a, b) if (rooms[a].rect.center[1 if axis == "x" else 0] < c) else (b, a)
        out.append(Doorway(len(out), _xy(axis, u, c), axis, width, height, (lo_side, hi_side)))
    return out


# ------------------------------------------------------------------------------ walls
def _wall_pieces(rects: list[Rect]) -> list[_Piece]:
    """Every room edge split into stretches with one room pair each (shared stretches once)."""
    pieces: list[_Piece] = []
    for axis in ("x", "y"):
        # for a wall along x, the line is y = c; rooms below have ymax = c, above ymin = c
        def lo_hi(r: Rect) -> tuple[float, float, float, float]:
            return (r.xmin, r.xmax, r.ymin, r.ymax) if axis == "x" else (r.ymin, r.ymax, r.xmin, r.xmax)  # noqa: B023 (used within this iteration)

        coords = sorted({v for r in rects for v in lo_hi(r)[2:]})
        for c in coords:
            below = [(i, lo_hi(r)) for i, r in enumerate(rects) if abs(lo_hi(r)[3] - c) < _EPS]
            above = [(i, lo_hi(r)) for i, r in enumerate(rects) if abs(lo_hi(r)[2] - c) < _EPS]
            cuts = sorted({v for _, e in below + above for v in e[:2]})
            for p, q in zip(cuts[:-1], cuts[1:]):
                if q - p < _EPS:
                    continue
                m = (p + q) / 2.0
                b = next((i for i, e in below if e[0] - _EPS <= m <= e[1] + _EPS), -1)
                a = next((i for i, e in above if e[0] - _EPS <= m <= e[1] + _EPS), -1)
                if a == -1 and b == -1:
                    continue
                if pieces and pieces[-1].axis == axis and pieces[-1].coord == c and pieces[-1].rooms == (b, a) and abs(pieces[-1].hi - p) < _EPS:
                    pieces[-1] = dataclasses.replace(pieces[-1], hi=q)
                else:
                    pieces.append(_Piece(axis, c, p, q, (b, a)))
    return pieces


def _segments(pieces: list[_Piece], doorways: list[Doorway], t: float, height: float, rooms: list[Room]) -> list[WallSegment]:
    """Wall segments: pieces minus doorway openings; walls along x extend by t/2 to close corners."""
    segs: list[WallSegment] = []
    for p in pieces:
        cuts = sorted(
            (dw.center[0] if p.axis == "x" else dw.center[1], dw.width)
            for dw in doorways
            if dw.axis == p.axis
            and abs((dw.center[1] if p.axis == "x" else dw.center[0]) - p.coord) < _EPS
            and p.lo < (dw.center[0] if p.axis == "x" else dw.center[1]) < p.hi
        )
        # close the corners: walls along x reach over the crossing walls, but only at the
        # ends of their line (collinear neighbours must not overlap)
        same_line = [o for o in pieces if o.axis == p.axis and o.coord == p.coord and o is not p]
        ext_lo = t / 2.0 if p.axis == "x" and not any(abs(o.hi - p.lo) < _EPS for o in same_line) else 0.0
        ext_hi = t / 2.0 if p.axis == "x" and not any(abs(o.lo - p.hi) < _EPS for o in same_line) else 0.0
        u = p.lo - ext_lo
        spans: list[tuple[float, float]] = []
        for cu, w in cuts:
            spans.append((u, cu - w / 2.0))
            u = cu + w / 2.0
        spans.append((u, p.hi + ext_hi))
        room = rooms[p.rooms[0] if p.rooms[0] >= 0 else p.rooms[1]]
        for s0, s1 in spans:
            if s1 - s0 < 0.01:
                continue
            segs.append(
                WallSegment(
                    a=_xy(p.axis, round(s0, 4), p.coord),
                    b=_xy(p.axis, round(s1, 4), p.coord),
                    thickness=t,
                    height=height,
                    material=room.wall_material,
                    exterior=p.exterior,
                )
            )
    return segs


# ------------------------------------------------------------------------------ doors
def _doorway_zone(dw: Doorway, depth: float, side: float) -> Rect:
    """Area in front of a doorway (both sides), widened by `side` beyond its edges."""
    cu, cv = (dw.center[0], dw.center[1]) if dw.axis == "x" else (dw.center[1], dw.center[0])
    return _rect_uv(dw.axis, cu - dw.width / 2.0 - side, cu + dw.width / 2.0 + side, cv - depth, cv + depth)


def _side_room(dw: Doorway, room: Room, t: float) -> tuple[float, float]:
    """Free wall inside `room` beyond the doorway's low-u and high-u edges."""
    inner = room.rect.expanded(-t / 2.0)
    cu = dw.center[0] if dw.axis == "x" else dw.center[1]
    lo, hi = (inner.xmin, inner.xmax) if dw.axis == "x" else (inner.ymin, inner.ymax)
    return (cu - dw.width / 2.0 - lo, hi - (cu + dw.width / 2.0))


def _pick_doorway(
    piece: _Piece,
    width: float,
    t: float,
    taken: list[Doorway],
    rng: np.random.Generator,
    index: int,
    height: float,
    opened_from: Room | None = None,
) -> Doorway | None:
    """A doorway on `piece`, DOORWAY_CORNER_MARGIN from its ends, clear of other doorways' zones.

    `opened_from`: the door will be opened from this room, so one side needs
    DOOR_HINGE_SIDE_ROOM of wall there.
    """
    margin = t / 2.0 + DOORWAY_CORNER_MARGIN + width / 2.0
    lo, hi = piece.lo + margin, piece.hi - margin
    if hi < lo:
        return None
    for _ in range(8):
        cu = _r2(rng.uniform(lo, hi))
        dw = Doorway(index, _xy(piece.axis, cu, piece.coord), piece.axis, width, height, piece.rooms)
        if opened_from is not None and max(_side_room(dw, opened_from, t)) < DOOR_HINGE_SIDE_ROOM:
            continue
        zone = _doorway_zone(dw, DOOR_CLEARANCE_DEPTH, DOOR_CLEARANCE_SIDE)
        if all(not zone.intersects(_doorway_zone(o, DOOR_CLEARANCE_DEPTH, DOOR_CLEARANCE_SIDE)) for o in taken):
            return dw
    return None


def _make_door(
    dw: Doorway, door_index: int, swing_room: Room, t: float, bell: bool, rng: np.random.Generator, material: str
) -> Door:
    """A leaf hung on the swing-side wall face, hinge axis outside that face (docs/SIMULATION_NOTES.md#articulations)."""
    cu, cv = (dw.center[0], dw.center[1]) if dw.axis == "x" else (dw.center[1], dw.center[0])
    room_v = swing_room.rect.center[1] if dw.axis == "x" else swing_room.rect.center[0]
    s = 1.0 if room_v > cv else -1.0  # swing side along the wall normal
    hinge_low = bool(rng.random() < 0.5)  # hinge at the low-u end of the opening
    if bell:  # it will be opened: the hinge goes where the wall leaves room for the robot
        room_low, room_high = _side_room(dw, swing_room, t)
        hinge_low = room_low >= room_high
    width = dw.width + 2.0 * DOOR_OVERLAP
    hu = cu - dw.width / 2.0 - DOOR_OVERLAP if hinge_low else cu + dw.width / 2.0 + DOOR_OVERLAP
    hv = cv + s * (t / 2.0 + DOOR_FACE_GAP + DOOR_THICKNESS / 2.0)
    along = 1.0 if hinge_low else -1.0  # hinge -> free edge along u
    dx, dy = _xy(dw.axis, along, 0.0)
    closed_yaw = math.atan2(dy, dx)
    nx, ny = _xy(dw.axis, 0.0, s)
    # a small CCW turn moves the free edge along (-sin, cos) of the leaf direction
    open_sign = 1.0 if (-math.sin(closed_yaw) * nx + math.cos(closed_yaw) * ny) > 0 else -1.0
    doorbell = None
    if bell:
        latch_u = cu + (dw.width / 2.0 + DOORBELL_BESIDE) * (1.0 if hinge_low else -1.0)
        bv = cv + s * (t / 2.0 + 0.01)
        bx, by = _xy(dw.axis, latch_u, bv)
        doorbell = (round(bx, 3), round(by, 3), DOORBELL_Z)
    hx, hy = _xy(dw.axis, hu, hv)
    return Door(
        index=door_index,
        doorway=dw.index,
        hinge=(round(hx, 4), round(hy, 4)),
        closed_yaw=closed_yaw,
        open_sign=open_sign,
        width=width,
        thickness=DOOR_THICKNESS,
        height=dw.height - 0.02,
        max_angle=DOOR_MAX_ANGLE,
        open_threshold=DOOR_OPEN_THRESHOLD,
        angle=0.0,
        handle_height=DOOR_HANDLE_HEIGHT,
        swing_room=swing_room.index,
        material=material,
        doorbell=doorbell,
    )


def door_swing_zone(door: Door) -> Rect:
    """Bounding box of everything the leaf sweeps from closed to max angle (plus 5 cm)."""
    pts = [door.hinge]
    for q in np.linspace(0.0, door.max_angle, 12):
        pts.append(door.free_edge(float(q)))
    for q in (0.0, door.max_angle):
        yaw = door.leaf_yaw(q)
        pts.append((door.hinge[0] - math.sin(yaw) * door.thickness, door.hinge[1] + math.cos(yaw) * door.thickness))
    xs = [p[0] for p in pts]
    ys = [p[1] for p in pts]
    return Rect(min(xs) - 0.05, min(ys) - 0.05, max(xs) + 0.05, max(ys) + 0.05)


def door_operation_zone(door: Door) -> Rect:
    """Floor the robot's base may sweep while opening `door` (swing side; see DOOR_HINGE_SIDE_ROOM)."""
    d = (math.cos(door.closed_yaw), math.sin(door.closed_yaw))  # hinge -> free edge
    n = (-door.open_sign * d[1], door.open_sign * d[0])  # swing side
    pts = [
        (door.hinge[0] + a * d[0] + b * n[0], door.hinge[1] + a * d[1] + b * n[1])
        for a in (-(DOOR_HINGE_SIDE_ROOM - DOOR_OVERLAP), door.width + 0.1)
        for b in (0.0, DOOR_OPERATION_DEPTH)
    ]
    xs, ys = [p[0] for p in pts], [p[1] for p in pts]
    return Rect(min(xs), min(ys), max(xs), max(ys))


def _spanning_doorways(
    rooms: list[Room],
    pieces: list[_Piece],
    recipe: Recipe,
    rng: np.random.Generator,
    opened: list[Doorway] | None = None,
    hubs: frozenset[int] = frozenset(),
) -> list[Doorway] | None:
    """Random spanning tree over rooms that share a wall long enough for a doorway; the rooms
    joined by the wide openings `opened` (listed first) count as connected already, and walls
    of the `hubs` (a corridor) get their doorways first, so rooms open off the corridor."""
    t = recipe.scene.wall_thickness
    width = recipe.scene.doorway_width
    height = min(DOORWAY_HEIGHT, recipe.scene.wall_height - 0.3)
    need = width + 2.0 * (t / 2.0 + DOORWAY_CORNER_MARGIN)
    best: dict[tuple[int, int], _Piece] = {}
    for p in pieces:
        if p.exterior or p.length < need:
            continue
        key = (min(p.rooms), max(p.rooms))
        if key not in best or p.length > best[key].length:
            best[key] = p
    edges = sorted(best)
    order = rng.permutation(len(edges))
    if hubs:
        order = np.asarray(sorted(order, key=lambda k: not set(edges[int(k)]) & hubs))
    parent = list(range(len(rooms)))

    def find(i: int) -> int:
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    doorways: list[Doorway] = list(opened or ())
    for joined in doorways:
        parent[find(joined.rooms[0])] = find(joined.rooms[1])
    for k in order:
        a, b = edges[int(k)]
        ra, rb = find(a), find(b)
        if ra == rb:
            continue
        dw = _pick_doorway(best[(a, b)], width, t, doorways, rng, len(doorways), height)
        if dw is None:
            continue
        parent[ra] = rb
        doorways.append(dw)
    if len({find(i) for i in range(len(rooms))}) != 1:
        return None
    return doorways
