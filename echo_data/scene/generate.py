"""Procedural apartments: rooms, walls with doorways, doors, furniture, sink + faucet, clutter.

`generate_floorplan` is a pure function of (recipe, rng). The rooms' rectangles come from a
layout family (`echo_data.scene.layouts`: rows, an L-shaped room, a corridor, an open-plan
kitchen/living room); walls are the room outlines with each shared stretch listed once and
doorways cut out; rectangles of one space are joined by a wide doorless opening, a random
spanning tree of doorways connects the rest, and one exterior doorway (the entrance) always
carries a hinged door with a doorbell. Furniture stands against walls facing the room, away from doorway zones
and door swings, each with a free strip in front of it for the robot. The sounding targets
are placed later by the episode sampler (`place_object`); here only silent distractors go
onto receptacles.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from echo_data import seeds
from echo_data.recipe import Recipe
from echo_data.scene.floorplan import (
    Door,
    Doorway,
    Faucet,
    FloorPlan,
    Furnishing,
    Furniture,
    PlacedObject,
    Rect,
    Room,
    WallSegment,
)
from echo_data.scene.layouts import Layout, draw_family, draw_layout, opening_span
from echo_data.scene.objects import instance_scale, object_size
from echo_data.scene.surfaces import room_floor

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

# --- furniture -------------------------------------------------------------------------
WALL_GAP = 0.02  # furniture back to wall face
FURNITURE_GAP = 0.05
FRONT_FREE_DEPTH = 1.0  # free strip in front of every piece (robot stands there)
ROBOT_RADIUS = 0.3
CORRIDOR = 0.9


@dataclass(frozen=True)
class FurnitureSpec:
    """Size ranges of one furniture kind: along the wall, depth from the wall, height."""

    along: tuple[float, float]
    depth: tuple[float, float]
    height: tuple[float, float]
    receptacle: bool


FURNITURE_SPECS: dict[str, FurnitureSpec] = {
    "table": FurnitureSpec((1.0, 1.4), (0.6, 0.8), (0.75, 0.75), True),
    "counter": FurnitureSpec((1.2, 2.0), (0.6, 0.65), (0.9, 0.9), True),
    "shelf": FurnitureSpec((0.8, 1.2), (0.4, 0.45), (0.6, 0.8), True),
    "cabinet": FurnitureSpec((0.6, 1.0), (0.45, 0.55), (0.6, 0.8), True),
    "sofa": FurnitureSpec((1.8, 2.2), (0.85, 0.95), (0.8, 0.8), False),
    "bed": FurnitureSpec((0.9, 1.6), (1.9, 2.1), (0.5, 0.5), False),
    "sink_cabinet": FurnitureSpec((0.8, 1.0), (0.5, 0.55), (0.85, 0.85), False),
}
ROOM_FURNITURE: dict[str, tuple[str, ...]] = {
    "living": ("sofa", "table", "shelf", "cabinet"),
    "kitchen": ("counter", "table", "cabinet"),
    "bedroom": ("bed", "shelf", "cabinet", "table"),
    "bathroom": ("cabinet", "shelf"),
    "hall": ("shelf", "cabinet"),
    "study": ("table", "shelf", "cabinet"),
}
SINK_ROOMS = ("kitchen", "bathroom")

# --- soft furnishings (acoustic absorbers; the visual and the acoustic scene share them) ---
# Absorption coefficients are pyroomacoustics' database entries (tabulated from Vorländer,
# "Auralization", appendix); seating entries are given per m^2 of floor the seats cover,
# which is how `echo_data.acoustics.tail` counts upholstered furniture.
UPHOLSTERY: dict[str, str] = {
    "sofa": "chairs_upholstered_cloth",  # cloth-covered upholstery, 0.77 at 500 Hz
    "bed": "chairs_heavy_upholstered",  # mattress under a duvet: heavily upholstered, 0.81 at 500 Hz
}
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

# --- faucet ----------------------------------------------------------------------------
# Pivot behind the cabinet's front face: in the back half of the top, yet within the reach
# of a Fetch arm pushing the lever from the front (CloseSink expert: 0.3-0.4 m works,
# 0.45 m does not).
FAUCET_FRONT_DEPTH = 0.34
FAUCET_PIVOT_HEIGHT = 0.15  # above the counter top
FAUCET_LEVER_LENGTH = 0.13
FAUCET_OPEN_ANGLE = math.pi / 2.0
FAUCET_START_ANGLE = 1.2  # running
FAUCET_CLOSED_TOLERANCE = 0.1
FAUCET_SPOUT_REACH = 0.13  # spout mouth in front of the pivot
FAUCET_SPOUT_HEIGHT = 0.1  # above the counter top

# --- objects ---------------------------------------------------------------------------
EDGE_MARGIN = 0.08  # object footprint to receptacle edge
FRONT_REACH = 0.35  # object centre to receptacle front edge, at most
OBJECT_GAP = 0.03
OBJECT_WALL_CLEARANCE = 0.25  # object centre to any wall face of its room
REST_LIFT = 0.0  # objects rest exactly on the top (z = top + sz / 2)

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


# ------------------------------------------------------------------------------ furniture
def _inner(room: Room, t: float) -> Rect:
    return room.rect.expanded(-t / 2.0)


def front_zone(f: Furniture, depth: float = FRONT_FREE_DEPTH) -> Rect:
    """The strip in front of a piece of furniture where the robot stands to use it."""
    fp = f.footprint
    c, s = round(math.cos(f.yaw)), round(math.sin(f.yaw))
    if c > 0:
        return Rect(fp.xmax, fp.ymin, fp.xmax + depth, fp.ymax)
    if c < 0:
        return Rect(fp.xmin - depth, fp.ymin, fp.xmin, fp.ymax)
    if s > 0:
        return Rect(fp.xmin, fp.ymax, fp.xmax, fp.ymax + depth)
    return Rect(fp.xmin, fp.ymin - depth, fp.xmax, fp.ymin)


def _place_furniture(
    kind: str,
    room: Room,
    index: int,
    placed: list[Furniture],
    keepout: list[Rect],
    swings: list[Rect],
    t: float,
    material: str,
    rng: np.random.Generator,
    tries: int = 30,
) -> Furniture | None:
    """One piece against a random wall of `room`, front towards the room, clear of everything."""
    spec = FURNITURE_SPECS[kind]
    inner = _inner(room, t)
    for _ in range(tries):
        side = int(rng.integers(4))  # 0 south, 1 north, 2 west, 3 east
        along = _r2(rng.uniform(*spec.along))
        depth = _r2(rng.uniform(*spec.depth))
        height = _r2(rng.uniform(*spec.height))
        if side in (0, 1):
            span = inner.xmax - inner.xmin - along - 0.04
            if span < 0:
                continue
            cx = inner.xmin + 0.02 + along / 2.0 + rng.uniform(0.0, span)
            cy = inner.ymin + WALL_GAP + depth / 2.0 if side == 0 else inner.ymax - WALL_GAP - depth / 2.0
            size = (along, depth, height)
            yaw = math.pi / 2.0 if side == 0 else -math.pi / 2.0
        else:
            span = inner.ymax - inner.ymin - along - 0.04
            if span < 0:
                continue
            cy = inner.ymin + 0.02 + along / 2.0 + rng.uniform(0.0, span)
            cx = inner.xmin + WALL_GAP + depth / 2.0 if side == 2 else inner.xmax - WALL_GAP - depth / 2.0
            size = (depth, along, height)
            yaw = 0.0 if side == 2 else math.pi
        f = Furniture(index, kind, room.index, (round(cx, 3), round(cy, 3)), size, yaw, UPHOLSTERY.get(kind, material), spec.receptacle)
        fp, fz = f.footprint, front_zone(f)
        if not inner.contains(fz.xmin, fz.ymin) or not inner.contains(fz.xmax, fz.ymax):
            continue
        if any(fp.intersects(k) for k in keepout):
            continue
        if any(fz.intersects(k) for k in swings):
            continue  # an opened door would block the robot's spot
        if any(fp.intersects(o.footprint, FURNITURE_GAP) or fz.intersects(o.footprint) or fp.intersects(front_zone(o)) for o in placed):
            continue
        return f
    return None


def _room_connected(room: Room, furniture: list[Furniture], doorways: list[Doorway], t: float) -> bool:
    """Whether every furniture front and every doorway of the room lie in one free region
    for a base of radius ROBOT_RADIUS (a 5 cm raster of the room)."""
    res = 0.05
    inner = _inner(room, t)
    nx = int(round((inner.xmax - inner.xmin) / res))
    ny = int(round((inner.ymax - inner.ymin) / res))
    xs = inner.xmin + (np.arange(nx) + 0.5) * res
    ys = inner.ymin + (np.arange(ny) + 0.5) * res
    gx, gy = np.meshgrid(xs, ys)
    free = (
        (gx - inner.xmin >= ROBOT_RADIUS)
        & (inner.xmax - gx >= ROBOT_RADIUS)
        & (gy - inner.ymin >= ROBOT_RADIUS)
        & (inner.ymax - gy >= ROBOT_RADIUS)
    )
    for f in furniture:
        fp = f.footprint.expanded(ROBOT_RADIUS)
        free &= ~((gx > fp.xmin) & (gx < fp.xmax) & (gy > fp.ymin) & (gy < fp.ymax))
    labels, _ = ndimage.label(free)

    def label_at(x: float, y: float) -> int:
        j = int(np.clip((x - inner.xmin) / res, 0, nx - 1))
        i = int(np.clip((y - inner.ymin) / res, 0, ny - 1))
        return int(labels[i, j])

    seen: set[int] = set()
    for f in furniture:
        z = front_zone(f)
        seen.add(label_at(*z.center))
    for dw in doorways:
        if room.index not in dw.rooms:
            continue
        # a point half a metre inside the room in front of the doorway
        cu, cv = (dw.center[0], dw.center[1]) if dw.axis == "x" else (dw.center[1], dw.center[0])
        room_v = room.rect.center[1] if dw.axis == "x" else room.rect.center[0]
        v = cv + (0.5 if room_v > cv else -0.5)
        seen.add(label_at(*_xy(dw.axis, cu, v)))
    return 0 not in seen and len(seen) <= 1


# ------------------------------------------------------------------------------ objects
def _front_frame(f: Furniture) -> tuple[tuple[float, float], tuple[float, float], float, float]:
    """Front normal, lateral axis, half depth (along the normal), half length (lateral)."""
    n = (float(round(math.cos(f.yaw))), float(round(math.sin(f.yaw))))
    lat = (-n[1], n[0])
    half_depth = (abs(n[0]) * f.size[0] + abs(n[1]) * f.size[1]) / 2.0
    half_len = (abs(lat[0]) * f.size[0] + abs(lat[1]) * f.size[1]) / 2.0
    return n, lat, half_depth, half_len


def object_radius(category: str, scale: float = 1.0) -> float:
    """Radius of the circle that holds an object's footprint at any yaw."""
    sx, sy, _ = object_size(category, scale)
    return math.hypot(sx, sy) / 2.0


def place_object(
    plan: FloorPlan,
    category: str,
    name: str,
    rng: np.random.Generator,
    sounding: bool,
    receptacles: list[int] | None = None,
    tries: int = 40,
    scale: float = 1.0,
) -> FloorPlan | None:
    """`plan` plus one object of `category` resting on a receptacle, or None if none fits.

    The object sits EDGE_MARGIN inside the top's edges, its centre within FRONT_REACH of
    the front edge (a Fetch arm reaches it from the front strip), clear of other objects;
    its long side runs along the front edge (the gripper closes across the narrow side);
    it keeps OBJECT_WALL_CLEARANCE from the room's walls (room for the arm in corners).
    """
    cands = [f.index for f in plan.furniture if f.receptacle] if receptacles is None else list(receptacles)
    if not cands:
        return None
    r = object_radius(category, scale)
    sz = object_size(category, scale)[2]
    t = plan.walls[0].thickness if plan.walls else 0.0
    for _ in range(tries):
        f = plan.furniture[cands[int(rng.integers(len(cands)))]]
        n, lat, half_depth, half_len = _front_frame(f)
        room_inner = plan.rooms[f.room].rect.expanded(-t / 2.0)
        u_max = half_len - EDGE_MARGIN - r
        d_lo = EDGE_MARGIN + r
        d_hi = min(FRONT_REACH, 2.0 * half_depth - EDGE_MARGIN - r)
        if u_max < 0 or d_hi < d_lo:
            continue
        u = rng.uniform(-u_max, u_max)
        d = rng.uniform(d_lo, d_hi)  # from the front edge
        x = f.center[0] + n[0] * (half_depth - d) + lat[0] * u
        y = f.center[1] + n[1] * (half_depth - d) + lat[1] * u
        if not room_inner.contains(x, y, margin=OBJECT_WALL_CLEARANCE):
            continue  # an arm reaching into a corner hits the side wall
        if any(
            math.hypot(o.position[0] - x, o.position[1] - y) < r + object_radius(o.category, o.scale) + OBJECT_GAP
            for o in plan.objects
        ):
            continue
        yaw = math.atan2(lat[1], lat[0]) + rng.uniform(-0.3, 0.3)
        yaw = math.atan2(math.sin(yaw), math.cos(yaw))
        obj = PlacedObject(
            index=len(plan.objects),
            name=name,
            category=category,
            position=(round(x, 4), round(y, 4), round(f.top_z + sz / 2.0 + REST_LIFT, 4)),
            yaw=round(yaw, 4),
            receptacle=f.index,
            sounding=sounding,
            scale=scale,
        )
        return dataclasses.replace(plan, objects=plan.objects + (obj,))
    return None


# ------------------------------------------------------------------------------ main
def generate_floorplan(recipe: Recipe, rng: np.random.Generator) -> FloorPlan:
    """A random apartment for `recipe`; deterministic per rng state.

    The plan's `seed` is drawn from `rng` first and everything else from a generator seeded
    with it, so `generate_floorplan(recipe, np.random.default_rng(...))` with the same draw
    reproduces the plan and the seed stored in the plan identifies it.
    """
    seed = int(rng.integers(0, 2**63 - 1))
    return generate_floorplan_from_seed(recipe, seed)


def generate_floorplan_from_seed(recipe: Recipe, seed: int, max_tries: int = 40) -> FloorPlan:
    """The apartment identified by (recipe, seed)."""
    rng = np.random.default_rng(seed)
    family = draw_family(recipe, rng)
    for _ in range(max_tries):
        plan = _try_generate(recipe, rng, seed, family)
        if plan is not None:
            return plan
    raise GenerationError(f"no valid apartment in {max_tries} tries (seed {seed}); loosen recipe.scene")


def _try_generate(recipe: Recipe, rng: np.random.Generator, seed: int, family: str) -> FloorPlan | None:
    sc = recipe.scene
    t = sc.wall_thickness
    layout = draw_layout(recipe, family, rng)
    if layout is None:
        return None
    rects = layout.rects
    kinds = _assign_kinds(rects, rng) if layout.family == "rows" else _assign_space_kinds(layout, rng)
    if not kinds:
        return None
    rooms = [
        Room(
            index=i,
            kind=kinds[i],
            rect=r,
            floor_material=str(rng.choice(sc.floor_materials)),
            wall_material=str(rng.choice(sc.wall_materials)),
            ceiling_material=str(rng.choice(sc.ceiling_materials)),
        )
        for i, r in enumerate(rects)
    ]
    rooms = _room_surfaces(rooms, layout, sc.wet_floor_materials, seed)
    height = min(DOORWAY_HEIGHT, sc.wall_height - 0.3)
    pieces = _wall_pieces(rects)
    opened = _wide_openings(layout, rooms, t, sc.wall_height)
    doorways = _spanning_doorways(rooms, pieces, recipe, rng, opened, layout.no_entrance)
    if doorways is None:
        return None
    # entrance: an exterior wall of the hall / living room / any room, in that order (never
    # into a narrow corridor, where the leaf would close the hall)
    pref = {"hall": 0, "living": 1}
    ext = sorted(
        (p for p in pieces if p.exterior and max(p.rooms) not in layout.no_entrance),
        key=lambda p: (pref.get(rooms[max(p.rooms)].kind, 2), -p.length),
    )
    entrance = None
    for p in ext:
        entrance = _pick_doorway(p, sc.doorway_width, t, doorways, rng, len(doorways), height, opened_from=rooms[max(p.rooms)])
        if entrance is not None:
            break
    if entrance is None:
        return None
    doorways.append(entrance)

    door_material = "wooden_door"
    doors: list[Door] = []
    for dw in doorways:
        if dw in opened:
            continue  # a wide opening has no door
        is_entrance = dw is entrance
        draw = 1.0 if is_entrance else rng.random()
        # a bathroom is never left without a door (where wet rooms are modelled, see
        # `scene.wet_floor_materials`): its hard, ringing room stays shut off from the others
        bath = sc.wet_floor_materials is not None and any(r >= 0 and rooms[r].kind == "bathroom" for r in dw.rooms)
        if not is_entrance and draw >= sc.door_probability and not bath:
            continue
        if is_entrance:
            swing = rooms[max(dw.rooms)]
        elif layout.no_entrance & set(dw.rooms):  # into the room, never into a narrow hall
            swing = rooms[next(r for r in dw.rooms if r not in layout.no_entrance)]
        else:
            swing = rooms[dw.rooms[int(rng.integers(2))]]
        bell = is_entrance or bool(rng.random() < INTERIOR_BELL_PROBABILITY)
        if not is_entrance and max(_side_room(dw, swing, t)) < DOOR_HINGE_SIDE_ROOM:
            bell = False  # no room beside it to open it
        doors.append(_make_door(dw, len(doors), swing, t, bell, rng, door_material))

    swings = [door_swing_zone(d) for d in doors] + [door_operation_zone(d) for d in doors if d.doorbell is not None]
    keepout = [_doorway_zone(dw, DOOR_CLEARANCE_DEPTH, DOOR_CLEARANCE_SIDE) for dw in doorways] + swings

    furniture: list[Furniture] = []
    fmat = list(sc.furniture_materials)
    sink_rooms = [r for r in rooms if r.kind in SINK_ROOMS]
    sink_rooms = [sink_rooms[int(i)] for i in rng.permutation(len(sink_rooms))]
    sink: Furniture | None = None
    for room in sink_rooms:
        sink = _place_furniture("sink_cabinet", room, 0, furniture, keepout, swings, t, str(rng.choice(fmat)), rng)
        if sink is not None:
            furniture.append(sink)
            break
    if sink is None:
        return None
    # Rooms where the robot must work after a state event (sink room, belled doors' swing
    # rooms) get as much furniture as the recipe allows, receptacles first, so a second
    # (relocation) event usually finds a receptacle to take from and one to put on.
    key_rooms = {sink.room} | {d.swing_room for d in doors if d.doorbell is not None}
    lo_f, hi_f = sc.furniture_per_room
    for room in rooms:
        want = int(rng.integers(lo_f, hi_f + 1))
        if room.index in key_rooms and want > 0:
            want = max(want, min(hi_f, 3))
        have = sum(1 for f in furniture if f.room == room.index)
        kinds_here = ROOM_FURNITURE[room.kind]
        n_recep_first = 2 if room.index in key_rooms else 1
        for k in range(max(want - have, 0)):
            # the first piece(s) of a room are something to put things on
            pool = [c for c in kinds_here if FURNITURE_SPECS[c].receptacle] if k < n_recep_first else list(kinds_here)
            kind = pool[int(rng.integers(len(pool)))]
            f = _place_furniture(kind, room, len(furniture), furniture, keepout, swings, t, str(rng.choice(fmat)), rng)
            if f is None:
                continue
            here = [o for o in furniture if o.room == room.index] + [f]
            if _room_connected(room, here, doorways, t):
                furniture.append(f)
    for room in rooms:
        if not _room_connected(room, [f for f in furniture if f.room == room.index], doorways, t):
            return None
    # a relocation needs a receptacle to take from and another to put on: top up with
    # tables in the largest rooms (even when the recipe asks for bare rooms)
    for room in sorted(rooms, key=lambda r: (-r.rect.area, r.index)):
        if sum(1 for f in furniture if f.receptacle) >= 2:
            break
        f = _place_furniture("table", room, len(furniture), furniture, keepout, swings, t, str(rng.choice(fmat)), rng)
        if f is not None and _room_connected(room, [o for o in furniture if o.room == room.index] + [f], doorways, t):
            furniture.append(f)
    if sum(1 for f in furniture if f.receptacle) < 2:
        return None

    faucet = _make_faucet(sink)
    walls = _segments(pieces, doorways, t, sc.wall_height, rooms)
    plan = FloorPlan(
        seed=seed,
        rooms=tuple(rooms),
        walls=tuple(walls),
        doorways=tuple(doorways),
        doors=tuple(doors),
        furniture=tuple(furniture),
        faucets=(faucet,),
        objects=(),
        wall_height=sc.wall_height,
        extra=_layout_extra(layout, entrance.index, len(opened)),
        furnishings=_furnish(rooms, pieces, doorways, furniture, t, sc.wall_height, seeds.derived_rng(seeds.FURNISHINGS, seed)),
    )
    lo, hi = recipe.objects.distractors
    shapes = list(recipe.objects.distractor_shapes)
    n_distractors = int(rng.integers(lo, hi + 1)) if shapes else 0
    for k in range(n_distractors):
        cat = shapes[int(rng.integers(len(shapes)))]
        name = f"distractor_{k}"
        scale = instance_scale(cat, name, seed) if recipe.objects.size_variants else 1.0
        nxt = place_object(plan, cat, name, rng, sounding=False, scale=scale)
        if nxt is not None:
            plan = nxt
    return plan


def _room_surfaces(rooms: list[Room], layout: Layout, wet_floors: tuple[str, ...] | None, seed: int) -> list[Room]:
    """Rooms of one space share walls and ceiling (and the floor where they are the same kind);
    wet rooms get a hard floor (`surfaces.room_floor`). Draws from its own generator, so the
    apartment's other draws stay as they were."""
    out = list(rooms)
    for a, b in layout.joins:
        first = out[a]
        floor = first.floor_material if out[b].kind == first.kind else out[b].floor_material
        out[b] = dataclasses.replace(out[b], wall_material=first.wall_material, ceiling_material=first.ceiling_material, floor_material=floor)
    if wet_floors is not None:
        rng = seeds.derived_rng(seeds.WET_FLOORS, seed)
        out = [dataclasses.replace(r, floor_material=room_floor(r.floor_material, r.kind, wet_floors, int(rng.integers(1 << 30)))) for r in out]
    return out


def _layout_extra(layout: Layout, entrance: int, n_open: int) -> dict[str, object]:
    """`FloorPlan.extra`: the entrance doorway; for families other than rows also the family, the
    spaces of joined rooms and their openings (rows plans keep exactly the old keys)."""
    extra: dict[str, object] = {"entrance_doorway": entrance}
    if layout.family != "rows":
        extra["layout"] = layout.family
        extra["spaces"] = [list(j) for j in layout.joins]
        extra["open_doorways"] = list(range(n_open))
    return extra


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


def _make_faucet(sink: Furniture) -> Faucet:
    """Lever pivot in the back half of the cabinet top, pointing to the front when closed; starts running."""
    n, _, half_depth, _ = _front_frame(sink)
    top = sink.top_z
    back = FAUCET_FRONT_DEPTH - half_depth  # behind the centre
    px, py = sink.center[0] - n[0] * back, sink.center[1] - n[1] * back
    return Faucet(
        index=0,
        furniture=sink.index,
        pivot=(round(px, 4), round(py, 4), round(top + FAUCET_PIVOT_HEIGHT, 4)),
        yaw=sink.yaw,
        lever_length=FAUCET_LEVER_LENGTH,
        open_angle=FAUCET_OPEN_ANGLE,
        closed_tolerance=FAUCET_CLOSED_TOLERANCE,
        angle=FAUCET_START_ANGLE,
        spout=(
            round(px + n[0] * FAUCET_SPOUT_REACH, 4),
            round(py + n[1] * FAUCET_SPOUT_REACH, 4),
            round(top + FAUCET_SPOUT_HEIGHT, 4),
        ),
    )
