"""Geometry of the acoustic scene: rooms as shoeboxes, openings, occluders, image lattices.

The floor plan is axis-aligned rectangles, so every room is an exact shoebox whose inner
faces are the wall faces. That lets the image-source method use the closed-form shoebox
lattice per room (vectorised over receivers) and check the plan's non-convexity
separately: reflection points that fall into a doorway opening are no reflection, and path
segments are tested against the walls, lintels, door leaves and furniture. This is our own
code rather than pyroomacoustics' polygon ISM because (docs/SIMULATION_NOTES.md#acoustics) the latter needs
workarounds for receivers that see no image source, raises for mixed visibility (#441),
has no transmission or diffraction and does not reuse a source's images across a grid.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from echo_data.acoustics.types import SPEED_OF_SOUND
from echo_data.floorplan import FloorPlan, Room

# A door leaf within this angle of closed counts as a closed door (it seals its doorway).
CLOSED_DOOR_ANGLE = math.radians(6.0)
_EPS = 1e-3  # m; walls are shrunk by this so paths touching a face are not blocked


@dataclass(frozen=True)
class Opening:
    """A doorway as seen from one face of a room box (coordinates along that face)."""

    doorway: int
    face: int  # 0 x-lo, 1 x-hi, 2 y-lo, 3 y-hi
    u0: float  # extent along the face's in-plane horizontal axis
    u1: float
    height: float
    other_room: int  # box index (position in plan.rooms) on the far side, -1 outside
    openness: float  # 0 closed leaf ... 1 fully open (acoustic aperture share)
    closed: bool  # the leaf seals the opening (reflects like a panel, transmits with a loss)
    door_material: str | None


@dataclass
class RoomBox:
    """A room as a shoebox between its wall faces, floor and ceiling."""

    index: int  # position in plan.rooms
    lo: np.ndarray  # (3,)
    hi: np.ndarray  # (3,)
    room: Room
    openings: list[Opening] = field(default_factory=list)

    @property
    def size(self) -> np.ndarray:
        return self.hi - self.lo

    def contains(self, p: np.ndarray, margin: float = 0.0) -> np.ndarray:
        p = np.asarray(p, dtype=np.float64)
        return np.all((p >= self.lo - margin) & (p <= self.hi + margin), axis=-1)


def _face_offset(plan: FloorPlan, room: Room, axis: int, coord: float) -> float:
    """Half thickness of the wall whose centre line lies on the room's edge `coord`."""
    r = room.rect
    best = 0.0
    for w in plan.walls:
        const_axis = 1 if w.axis == "x" else 0  # a wall along x has constant y
        if const_axis != axis:
            continue
        c = w.a[const_axis]
        if abs(c - coord) > w.thickness / 2.0 + 1e-6:
            continue
        lo, hi = sorted((w.a[1 - const_axis], w.b[1 - const_axis]))
        rlo, rhi = (r.ymin, r.ymax) if axis == 0 else (r.xmin, r.xmax)
        if hi <= rlo + 1e-6 or lo >= rhi - 1e-6:
            continue
        best = max(best, w.thickness / 2.0 - abs(c - coord))
    return best


def room_boxes(plan: FloorPlan, door_angles: dict[int, float]) -> list[RoomBox]:
    """Shoebox per room (inner wall faces) with the doorways on each of its faces."""
    boxes: list[RoomBox] = []
    door_by_way = {d.doorway: d for d in plan.doors}
    pos = {r.index: i for i, r in enumerate(plan.rooms)}  # boxes are indexed by position
    for i_box, room in enumerate(plan.rooms):
        r = room.rect
        lo = np.array(
            [r.xmin + _face_offset(plan, room, 0, r.xmin), r.ymin + _face_offset(plan, room, 1, r.ymin), 0.0]
        )
        hi = np.array(
            [r.xmax - _face_offset(plan, room, 0, r.xmax), r.ymax - _face_offset(plan, room, 1, r.ymax), plan.wall_height]
        )
        box = RoomBox(i_box, lo, hi, room)
        for dw in plan.doorways:
            if room.index not in dw.rooms:
                continue
            # a doorway in a wall along x sits on a y-face of the room
            if dw.axis == "x":
                face = 2 if abs(dw.center[1] - r.ymin) < abs(dw.center[1] - r.ymax) else 3
                u = dw.center[0]
            else:
                face = 0 if abs(dw.center[0] - r.xmin) < abs(dw.center[0] - r.xmax) else 1
                u = dw.center[1]
            other = pos.get(dw.rooms[1] if dw.rooms[0] == room.index else dw.rooms[0], -1)
            door = door_by_way.get(dw.index)
            if door is None:
                openness, closed, mat = 1.0, False, None
            else:
                q = door_angles.get(door.index, door.angle)
                closed = q < CLOSED_DOOR_ANGLE
                # share of the doorway not shadowed by the leaf, projected on the doorway plane
                openness = 0.0 if closed else float(np.clip(1.0 - math.cos(min(q, math.pi / 2)), 0.0, 1.0))
                mat = door.material
            box.openings.append(
                Opening(dw.index, face, u - dw.width / 2.0, u + dw.width / 2.0, dw.height, other, openness, closed, mat)
            )
        boxes.append(box)
    return boxes


@dataclass
class Occluders:
    """Axis-aligned 3D boxes that block (walls, lintels), leak (closed doors) or diffract
    (furniture), plus open door leaves as oriented thin panels."""

    block_lo: np.ndarray  # (nb, 3)
    block_hi: np.ndarray
    door_lo: np.ndarray  # (nd, 3) closed doorways (the leaf seals the opening)
    door_hi: np.ndarray
    furn_lo: np.ndarray  # (nf, 3)
    furn_hi: np.ndarray
    leaf_a: np.ndarray  # (nl, 2) open leaves: hinge
    leaf_b: np.ndarray  # (nl, 2) free edge
    leaf_h: np.ndarray  # (nl,) height

    def local(self, box: RoomBox, margin: float = 0.05) -> Occluders:
        """What a segment inside `box` can meet: its furniture and nearby door leaves (a
        segment between two points of a convex box cannot cross a wall or lintel)."""
        lo, hi = box.lo[:2] - margin, box.hi[:2] + margin
        f = np.all((self.furn_hi[:, :2] > lo) & (self.furn_lo[:, :2] < hi), axis=1)
        la, lb = self.leaf_a, self.leaf_b
        l_ = np.all((np.maximum(la, lb) > lo) & (np.minimum(la, lb) < hi), axis=1) if len(la) else np.zeros(0, bool)
        e3 = np.zeros((0, 3))
        return Occluders(e3, e3, e3, e3, self.furn_lo[f], self.furn_hi[f], la[l_], lb[l_], self.leaf_h[l_])


def occluders(plan: FloorPlan, door_angles: dict[int, float]) -> Occluders:
    """Collect the plan's obstacles for segment tests."""
    big = plan.wall_height + 10.0
    blo, bhi = [], []
    for w in plan.walls:
        f = w.footprint
        blo.append((f.xmin + _EPS, f.ymin + _EPS, -10.0))
        bhi.append((f.xmax - _EPS, f.ymax - _EPS, big))
    door_by_way = {d.doorway: d for d in plan.doors}
    dlo, dhi = [], []
    for dw in plan.doorways:
        t = max((w.thickness for w in plan.walls), default=0.1)
        half_w = dw.width / 2.0
        if dw.axis == "x":
            x0, x1, y0, y1 = dw.center[0] - half_w, dw.center[0] + half_w, dw.center[1] - t / 2.0, dw.center[1] + t / 2.0
        else:
            x0, x1, y0, y1 = dw.center[0] - t / 2.0, dw.center[0] + t / 2.0, dw.center[1] - half_w, dw.center[1] + half_w
        # lintel above the opening
        blo.append((x0 - _EPS, y0 + _EPS, dw.height))
        bhi.append((x1 + _EPS, y1 - _EPS, big))
        door = door_by_way.get(dw.index)
        if door is not None and door_angles.get(door.index, door.angle) < CLOSED_DOOR_ANGLE:
            # the sealed opening between the two wall faces (paths touching a face, e.g. a
            # reflection off the closed leaf, do not pass through it)
            dlo.append((x0 + _EPS, y0 + _EPS, -10.0))
            dhi.append((x1 - _EPS, y1 - _EPS, dw.height))
    flo = [(f.footprint.xmin, f.footprint.ymin, 0.0) for f in plan.furniture]
    fhi = [(f.footprint.xmax, f.footprint.ymax, f.top_z) for f in plan.furniture]
    la, lb, lh = [], [], []
    for d in plan.doors:
        q = door_angles.get(d.index, d.angle)
        if q >= CLOSED_DOOR_ANGLE:
            la.append(d.hinge)
            lb.append(d.free_edge(q))
            lh.append(d.height)

    def arr(v: list, n: int) -> np.ndarray:
        return np.asarray(v, dtype=np.float64).reshape(-1, n)

    return Occluders(
        arr(blo, 3), arr(bhi, 3), arr(dlo, 3), arr(dhi, 3), arr(flo, 3), arr(fhi, 3), arr(la, 2), arr(lb, 2), np.asarray(lh)
    )


def segment_box(p0: np.ndarray, p1: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Slab test of segments (n, 3) against boxes (m, 3): (hit (n, m), t_in, t_out)."""
    d = p1 - p0
    d = np.where(np.abs(d) < 1e-12, 1e-12, d)
    inv = 1.0 / d
    t_in = np.zeros((len(p0), len(lo)))
    t_out = np.ones((len(p0), len(lo)))
    for a in range(3):  # per axis on (n, m) arrays: much faster than reducing a length-3 axis
        t1 = (lo[None, :, a] - p0[:, None, a]) * inv[:, None, a]
        t2 = (hi[None, :, a] - p0[:, None, a]) * inv[:, None, a]
        np.maximum(t_in, np.minimum(t1, t2), out=t_in)
        np.minimum(t_out, np.maximum(t1, t2), out=t_out)
    return t_in < t_out - 1e-9, t_in, t_out


def segment_leaf(p0: np.ndarray, p1: np.ndarray, a: np.ndarray, b: np.ndarray, h: np.ndarray) -> np.ndarray:
    """Whether segments (n, 3) pass through vertical panels a→b (m, 2) of height h: (n, m)."""
    if len(a) == 0:
        return np.zeros((len(p0), 0), dtype=bool)
    r = (p1 - p0)[:, None, :2]
    s = (b - a)[None, :, :]
    qp = a[None, :, :] - p0[:, None, :2]
    den = r[..., 0] * s[..., 1] - r[..., 1] * s[..., 0]
    den = np.where(np.abs(den) < 1e-12, 1e-12, den)
    t = (qp[..., 0] * s[..., 1] - qp[..., 1] * s[..., 0]) / den
    u = (qp[..., 0] * r[..., 1] - qp[..., 1] * r[..., 0]) / den
    z = p0[:, None, 2] + t * (p1 - p0)[:, None, 2]
    return (t > 0.0) & (t < 1.0) & (u >= -0.02) & (u <= 1.02) & (z < h[None, :])


def image_cells(order: int) -> np.ndarray:
    """Lattice cells (I, 3) of a shoebox's image sources with |cx|+|cy|+|cz| <= order, the
    real source first."""
    r = np.arange(-order, order + 1)
    c = np.stack(np.meshgrid(r, r, r, indexing="ij"), axis=-1).reshape(-1, 3)
    n = np.abs(c).sum(axis=1)
    c, n = c[n <= order], n[n <= order]
    return c[np.lexsort((c[:, 2], c[:, 1], c[:, 0], n))]


def mirror(p: np.ndarray, cells: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """Image of points p (..., 3) in lattice cells (..., 3) of the box [lo, hi]."""
    L = hi - lo
    u = p - lo
    return lo + cells * L + np.where(cells % 2 == 0, u, L - u)


def fold(v: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """Map unfolded lattice coordinates back into the real box (a triangle wave)."""
    L = hi - lo
    u = np.mod(v - lo, 2.0 * L)
    return lo + np.where(u <= L, u, 2.0 * L - u)


def opening_solid_angle(p: np.ndarray, op: Opening, plane: float) -> np.ndarray:
    """Solid angle (sr) under which points p (n, 3) see the rectangle of an opening that
    lies in the plane `plane` (normal along x for faces 0/1, along y for 2/3)."""
    a, u_axis = (0, 1) if op.face in (0, 1) else (1, 0)
    d = np.maximum(np.abs(p[:, a] - plane), 1e-4)
    us = (op.u0 - p[:, u_axis], op.u1 - p[:, u_axis])
    zs = (0.0 - p[:, 2], op.height - p[:, 2])

    def f(x: np.ndarray, y: np.ndarray) -> np.ndarray:
        return np.arctan2(x * y, d * np.sqrt(x * x + y * y + d * d))

    return f(us[1], zs[1]) - f(us[0], zs[1]) - f(us[1], zs[0]) + f(us[0], zs[0])


def diffraction_loss_db(delta: np.ndarray, freqs: np.ndarray, cap_db: float = 30.0) -> np.ndarray:
    """Edge-diffraction insertion loss (dB) for path detour `delta` (m) per frequency.

    Kurze–Anderson's barrier formula 5 + 20 log10(x / tanh x), x = sqrt(2 pi N), N = 2 delta / lambda,
    with its 5 dB grazing offset faded in as 5 tanh(x) so that the loss is 0 dB on the shadow
    boundary and the diffracted path joins the geometric one continuously. Capped (flanking).
    """
    n = 2.0 * np.maximum(delta, 0.0)[..., None] * freqs / SPEED_OF_SOUND
    x = np.sqrt(2.0 * np.pi * n)
    xs = np.maximum(x, 1e-9)
    il = 5.0 * np.tanh(x) + 20.0 * np.log10(xs / np.tanh(xs))
    return np.minimum(il, cap_db)
