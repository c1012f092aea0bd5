"""The floor-plan model: one description of an apartment that both the SAPIEN builder
(`echo_data.scene.build`) and the acoustics (`echo_data.acoustics`) read.

Conventions (used everywhere in echo-data):
- world frame: x east, y north, z up, metres; the floor is z = 0;
- yaw is counter-clockwise about +z in radians, 0 along +x;
- all walls and furniture footprints are axis-aligned in the plan (furniture yaw is a
  multiple of pi/2), which keeps rasterisation, acoustics and solvability checks exact.

Everything here is plain frozen data (JSON-serialisable via `to_dict` / `from_dict`) so an
episode spec can be written to disk and rebuilt on any machine with the same bytes.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from typing import Any

Vec2 = tuple[float, float]
Vec3 = tuple[float, float, float]


@dataclass(frozen=True)
class Rect:
    """Axis-aligned rectangle in the plan."""

    xmin: float
    ymin: float
    xmax: float
    ymax: float

    @property
    def center(self) -> Vec2:
        return ((self.xmin + self.xmax) / 2.0, (self.ymin + self.ymax) / 2.0)

    @property
    def size(self) -> Vec2:
        return (self.xmax - self.xmin, self.ymax - self.ymin)

    @property
    def area(self) -> float:
        return (self.xmax - self.xmin) * (self.ymax - self.ymin)

    def contains(self, x: float, y: float, margin: float = 0.0) -> bool:
        """True when (x, y) lies inside the rectangle shrunk by `margin`."""
        return (self.xmin + margin <= x <= self.xmax - margin) and (self.ymin + margin <= y <= self.ymax - margin)

    def intersects(self, other: Rect, margin: float = 0.0) -> bool:
        return not (
            self.xmax + margin <= other.xmin
            or other.xmax + margin <= self.xmin
            or self.ymax + margin <= other.ymin
            or other.ymax + margin <= self.ymin
        )

    def expanded(self, d: float) -> Rect:
        return Rect(self.xmin - d, self.ymin - d, self.xmax + d, self.ymax + d)


@dataclass(frozen=True)
class Room:
    """A rectangular room; `kind` drives furniture and material choice."""

    index: int
    kind: str  # living | kitchen | bedroom | bathroom | hall | study
    rect: Rect
    floor_material: str  # pyroomacoustics material name
    wall_material: str
    ceiling_material: str


@dataclass(frozen=True)
class WallSegment:
    """A solid, axis-aligned piece of wall; doorways are already cut out of it.

    `a`/`b` are the end points of the wall's centre line; the solid occupies
    `thickness` across it and [0, height] in z.
    """

    a: Vec2
    b: Vec2
    thickness: float
    height: float
    material: str
    exterior: bool

    @property
    def axis(self) -> str:
        """'x' when the wall runs along x, 'y' when it runs along y."""
        return "x" if abs(self.b[0] - self.a[0]) >= abs(self.b[1] - self.a[1]) else "y"

    @property
    def footprint(self) -> Rect:
        h = self.thickness / 2.0
        if self.axis == "x":
            return Rect(min(self.a[0], self.b[0]), self.a[1] - h, max(self.a[0], self.b[0]), self.a[1] + h)
        return Rect(self.a[0] - h, min(self.a[1], self.b[1]), self.a[0] + h, max(self.a[1], self.b[1]))


@dataclass(frozen=True)
class Doorway:
    """An opening in a wall joining two rooms (room -1 is outside the apartment)."""

    index: int
    center: Vec2  # on the wall centre line
    axis: str  # axis the wall runs along ('x' or 'y')
    width: float
    height: float
    rooms: tuple[int, int]


@dataclass(frozen=True)
class Door:
    """A hinged leaf hanging in a doorway (a SAPIEN articulation; an acoustic panel).

    The leaf is a box of `width` x `thickness` x `height` that, at hinge angle 0, extends
    from `hinge` in direction `closed_yaw`. The hinge angle q >= 0 turns the leaf about
    +z by `open_sign * q`. `swing_room` is the room the leaf swings into.
    """

    index: int
    doorway: int
    hinge: Vec2
    closed_yaw: float
    open_sign: float  # +1 counter-clockwise, -1 clockwise
    width: float
    thickness: float
    height: float
    max_angle: float  # rad, joint upper limit
    open_threshold: float  # rad, OpenDoor succeeds at or beyond this
    angle: float  # initial hinge angle (rad); 0 = closed
    handle_height: float
    swing_room: int
    material: str
    doorbell: Vec3 | None = None  # button on the wall beside the door, if this door has a bell

    def leaf_yaw(self, q: float | None = None) -> float:
        """Yaw of the leaf (hinge -> free edge) at hinge angle q (default: initial)."""
        return self.closed_yaw + self.open_sign * (self.angle if q is None else q)

    def free_edge(self, q: float | None = None) -> Vec2:
        yaw = self.leaf_yaw(q)
        return (self.hinge[0] + self.width * math.cos(yaw), self.hinge[1] + self.width * math.sin(yaw))


@dataclass(frozen=True)
class Furniture:
    """An axis-aligned block of furniture; receptacles hold objects on their top."""

    index: int
    kind: str  # table | counter | shelf | sink_cabinet | sofa | bed | cabinet
    room: int
    center: Vec2
    size: Vec3  # (sx, sy, height) in the plan frame, i.e. already rotated by yaw
    yaw: float  # front direction (multiple of pi/2): where a robot stands to use it
    material: str
    receptacle: bool

    @property
    def footprint(self) -> Rect:
        return Rect(
            self.center[0] - self.size[0] / 2.0,
            self.center[1] - self.size[1] / 2.0,
            self.center[0] + self.size[0] / 2.0,
            self.center[1] + self.size[1] / 2.0,
        )

    @property
    def top_z(self) -> float:
        return self.size[2]


@dataclass(frozen=True)
class Furnishing:
    """A soft furnishing: a rug on the floor or a curtain hanging in front of a wall.

    It absorbs sound (`material`, a pyroomacoustics name) and is seen by the cameras, but it
    is no obstacle: the robot drives over a rug, and a curtain hangs against a wall where the
    navigation grid is blocked anyway. Its absorbing area is the footprint (rug) or the face
    towards the room (curtain).
    """

    index: int
    kind: str  # rug | curtain
    room: int
    footprint: Rect
    z: tuple[float, float]  # bottom, top (m)
    material: str

    @property
    def area(self) -> float:
        """Absorbing area (m^2): the rug's top, or the curtain's face."""
        if self.kind == "rug":
            return self.footprint.area
        return max(self.footprint.size) * (self.z[1] - self.z[0])


@dataclass(frozen=True)
class Faucet:
    """A faucet lever on a sink cabinet: revolute joint, 0 = closed, `open_angle` = running.

    The water stream's flow follows the lever angle; it is off within `closed_tolerance`.
    """

    index: int
    furniture: int  # the sink cabinet
    pivot: Vec3  # lever joint position
    yaw: float  # direction the lever points when closed
    lever_length: float
    open_angle: float  # rad, joint upper limit
    closed_tolerance: float  # rad
    angle: float  # initial angle (rad)
    spout: Vec3  # where the water (and its sound) comes out


@dataclass(frozen=True)
class PlacedObject:
    """A rigid object resting on a receptacle: a sounding target or a silent distractor."""

    index: int
    name: str  # unique in the plan, e.g. "phone_0", "distractor_3"
    category: str  # phone | alarm | furby | mug | can | box | bowl | bottle | book ...
    position: Vec3  # centre of its collision shape at rest
    yaw: float
    receptacle: int  # furniture index it rests on
    sounding: bool
    scale: float = 1.0  # uniform size factor of this instance (`echo_data.scene.objects.instance_scale`)


@dataclass(frozen=True)
class FloorPlan:
    """A whole apartment."""

    seed: int
    rooms: tuple[Room, ...]
    walls: tuple[WallSegment, ...]
    doorways: tuple[Doorway, ...]
    doors: tuple[Door, ...]
    furniture: tuple[Furniture, ...]
    faucets: tuple[Faucet, ...]
    objects: tuple[PlacedObject, ...]
    wall_height: float = 2.5
    extra: dict[str, Any] = field(default_factory=dict)
    furnishings: tuple[Furnishing, ...] = ()

    @property
    def bounds(self) -> Rect:
        return Rect(
            min(r.rect.xmin for r in self.rooms),
            min(r.rect.ymin for r in self.rooms),
            max(r.rect.xmax for r in self.rooms),
            max(r.rect.ymax for r in self.rooms),
        )

    @property
    def open_doorways(self) -> frozenset[int]:
        """Doorways that are wide doorless openings joining the rooms of one space (an L-shaped
        room, an open-plan kitchen/living room; `echo_data.scene.layouts`)."""
        return frozenset(int(i) for i in self.extra.get("open_doorways", ()))

    def space_of(self, room: int) -> int:
        """The lowest index among the rooms that form one space with `room` (itself if alone)."""
        for a, b in self.extra.get("spaces", ()):
            if room in (a, b):
                return min(int(a), int(b))
        return room

    def room_at(self, x: float, y: float) -> int:
        """Index of the room containing (x, y), or -1."""
        for r in self.rooms:
            if r.rect.contains(x, y):
                return r.index
        return -1

    def object_by_name(self, name: str) -> PlacedObject:
        for o in self.objects:
            if o.name == name:
                return o
        raise KeyError(name)

    def to_dict(self) -> dict[str, Any]:
        """Plain data; an object at scale 1 is written without its `scale`, so plans made before
        instance sizes existed keep their bytes (and digests: tests/test_scene_layouts.py)."""
        d = dataclasses.asdict(self)
        for o in d["objects"]:
            if o["scale"] == 1.0:
                del o["scale"]
        return d

    @staticmethod
    def from_dict(d: dict[str, Any]) -> FloorPlan:
        def rect(v: dict[str, Any]) -> Rect:
            return Rect(**v)

        def tup(v: Any) -> Any:
            return tuple(v) if isinstance(v, list) else v

        rooms = tuple(Room(**{**r, "rect": rect(r["rect"])}) for r in d["rooms"])
        walls = tuple(WallSegment(**{**w, "a": tup(w["a"]), "b": tup(w["b"])}) for w in d["walls"])
        doorways = tuple(
            Doorway(**{**w, "center": tup(w["center"]), "rooms": tup(w["rooms"])}) for w in d["doorways"]
        )
        doors = tuple(
            Door(**{**w, "hinge": tup(w["hinge"]), "doorbell": tup(w["doorbell"])}) for w in d["doors"]
        )
        furniture = tuple(
            Furniture(**{**f, "center": tup(f["center"]), "size": tup(f["size"])}) for f in d["furniture"]
        )
        faucets = tuple(Faucet(**{**f, "pivot": tup(f["pivot"]), "spout": tup(f["spout"])}) for f in d["faucets"])
        objects = tuple(PlacedObject(**{**o, "position": tup(o["position"])}) for o in d["objects"])
        return FloorPlan(
            seed=d["seed"],
            rooms=rooms,
            walls=walls,
            doorways=doorways,
            doors=doors,
            furniture=furniture,
            faucets=faucets,
            objects=objects,
            wall_height=d.get("wall_height", 2.5),
            extra=dict(d.get("extra", {})),
            furnishings=tuple(
                Furnishing(**{**f, "footprint": rect(f["footprint"]), "z": tup(f["z"])}) for f in d.get("furnishings", ())
            ),
        )
