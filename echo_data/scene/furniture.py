"""Apartment generation, stage 2 (pure): furniture against the walls (with a free strip in
front of each piece for the robot), the sink cabinet's faucet, and objects on receptacles
(`place_object`, also used by the episode sampler for the sounding targets).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from echo_data.floorplan import (
    Doorway,
    Faucet,
    FloorPlan,
    Furniture,
    PlacedObject,
    Rect,
    Room,
)
from echo_data.scene.objects import object_size
from echo_data.scene.structure import _r2, _xy

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
# Absorption coefficients are pyroomacoustics' database entries (tabulated from Vorländer,
# "Auralization", appendix); seating entries are given per m^2 of floor the seats cover,
# which is how `echo_data.acoustics.tail` counts upholstered furniture.
UPHOLSTERY: dict[str, str] = {
    "sofa": "chairs_upholstered_cloth",  # cloth-covered upholstery, 0.77 at 500 Hz
    "bed": "chairs_heavy_upholstered",  # mattress under a duvet: heavily upholstered, 0.81 at 500 Hz
}

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
