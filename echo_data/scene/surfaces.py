"""The one owner of what a surface is made of: its acoustic material and how it looks.

A surface is named by its pyroomacoustics material (the acoustic scene reads the same names
from the floor plan); this module maps that name to a look — a texture pattern, a colour and a
roughness — so a carpeted floor or a rug is both seen as carpet and absorbs as carpet, a tiled
floor reflects like tiles and shows grout. Room style: which acoustic floor a room kind may get
(`room_floor`: no carpet in wet rooms) and which paint colours and floor prints (wood-effect or
tiled linoleum) its surfaces wear; paint and print change the look, never the absorption.

Everything here is pure (no SAPIEN): the build turns a `Look` into a render material.
"""

from __future__ import annotations

import zlib
from dataclasses import dataclass

# pattern, colour (linear RGB 0..1), roughness, metres per texture repeat
_MATERIAL_LOOKS: dict[str, tuple[str, tuple[float, float, float], float, float]] = {
    # walls
    "plasterboard": ("plaster", (0.93, 0.92, 0.88), 0.9, 2.0),
    "gypsum_board": ("plaster", (0.9, 0.9, 0.92), 0.9, 2.0),
    "brickwork": ("brick", (0.72, 0.42, 0.33), 0.9, 1.0),
    "rough_concrete": ("concrete", (0.62, 0.62, 0.6), 0.95, 2.0),
    "wooden_lining": ("wood", (0.7, 0.55, 0.38), 0.6, 1.0),
    "ceramic_tiles": ("tiles", (0.85, 0.9, 0.92), 0.2, 0.8),
    "ceiling_plasterboard": ("plaster", (0.95, 0.95, 0.94), 0.9, 2.0),
    # floors
    "linoleum_on_concrete": ("tiles", (0.62, 0.6, 0.55), 0.4, 1.2),  # print chosen per room, see ROOM_STYLE
    "carpet_cotton": ("carpet", (0.58, 0.45, 0.45), 1.0, 0.5),
    "carpet_thin": ("carpet", (0.45, 0.5, 0.62), 1.0, 0.5),
    "carpet_tufted_9.5mm": ("carpet", (0.5, 0.42, 0.36), 1.0, 0.5),
    "audience_floor": ("wood", (0.62, 0.48, 0.32), 0.5, 1.2),
    "stage_floor": ("wood", (0.55, 0.4, 0.26), 0.5, 1.2),
    "concrete_floor": ("concrete", (0.6, 0.6, 0.6), 0.8, 2.0),
    "marble_floor": ("tiles", (0.88, 0.88, 0.86), 0.15, 1.2),
    # doors, wooden furniture
    "wooden_door": ("wood", (0.55, 0.38, 0.22), 0.5, 1.0),
    # soft furnishings: rugs, curtains, upholstery (absorbers; see echo_data.acoustics.tail)
    "carpet_tufted_9m": ("carpet", (0.55, 0.2, 0.22), 1.0, 0.6),
    "carpet_1.35_kg_m2": ("carpet", (0.3, 0.35, 0.5), 1.0, 0.6),
    "carpet_hairy": ("carpet", (0.85, 0.8, 0.68), 1.0, 0.4),
    "carpet_6mm_open_cell_foam": ("carpet", (0.4, 0.5, 0.38), 1.0, 0.6),
    "curtains_cotton_0.5": ("fabric", (0.9, 0.86, 0.74), 1.0, 0.6),
    "curtains_densely_woven": ("fabric", (0.42, 0.5, 0.6), 1.0, 0.6),
    "curtains_fabric": ("fabric", (0.7, 0.58, 0.44), 1.0, 0.6),
    "curtains_velvet": ("fabric", (0.5, 0.15, 0.2), 0.9, 0.6),
    "chairs_upholstered_cloth": ("fabric", (0.3, 0.42, 0.62), 1.0, 0.5),
    "chairs_heavy_upholstered": ("fabric", (0.8, 0.66, 0.74), 1.0, 0.5),
}
# keyword fallbacks for recipe materials not in the table: the look of the material family
_FAMILY = (("carpet", "carpet"), ("curtain", "fabric"), ("chairs", "fabric"), ("tile", "tiles"), ("marble", "tiles"),
           ("wood", "wood"), ("plywood", "wood"), ("floor", "wood"), ("brick", "brick"), ("concrete", "concrete"))

# Room style: paint colours of plaster walls and the print of a linoleum floor.
ROOM_STYLE: dict[str, dict] = {
    "kitchen": {"paint": ((0.95, 0.92, 0.8), (0.88, 0.93, 0.85), (0.96, 0.9, 0.86)), "lino": "tiles"},
    "bathroom": {"paint": ((0.82, 0.9, 0.95), (0.88, 0.95, 0.93), (0.95, 0.95, 0.97)), "lino": "tiles"},
    "bedroom": {"paint": ((0.9, 0.85, 0.92), (0.85, 0.88, 0.95), (0.95, 0.9, 0.85)), "lino": "wood"},
    "living": {"paint": ((0.95, 0.9, 0.82), (0.88, 0.9, 0.86), (0.93, 0.88, 0.8)), "lino": "wood"},
    "study": {"paint": ((0.86, 0.9, 0.86), (0.92, 0.9, 0.86)), "lino": "wood"},
    "hall": {"paint": ((0.93, 0.93, 0.9), (0.9, 0.88, 0.84)), "lino": "wood"},
}
PAINTED = ("plaster",)
WET_ROOMS = ("kitchen", "bathroom")  # floors that get wet: never carpeted
SOFT_PATTERNS = ("carpet", "fabric")  # looks of absorbing (soft) materials

FURNITURE_LOOKS: dict[str, tuple[str, tuple[float, float, float], float]] = {
    # wooden furniture (the recipe's furniture materials are woods): pattern, colour, roughness;
    # upholstered furniture and any non-wood material follow the material's look
    "table": ("wood", (0.62, 0.45, 0.26), 0.5),
    "counter": ("wood", (0.78, 0.74, 0.66), 0.3),  # laminated worktop
    "shelf": ("wood", (0.48, 0.33, 0.2), 0.5),
    "cabinet": ("wood", (0.66, 0.5, 0.34), 0.5),
    "sink_cabinet": ("plain", (0.92, 0.92, 0.95), 0.3),  # painted wood
}


@dataclass(frozen=True)
class Look:
    """How a surface is drawn: texture pattern and variant, colour, roughness, repeat length (m)."""

    pattern: str
    variant: int
    colour: tuple[float, float, float]
    roughness: float
    period: float


def _salt(seed: int, *keys: object) -> int:
    return zlib.crc32(f"{seed}:{':'.join(map(str, keys))}".encode())


def _family(material: str) -> tuple[str, tuple[float, float, float], float, float]:
    if material in _MATERIAL_LOOKS:
        return _MATERIAL_LOOKS[material]
    pattern = next((p for key, p in _FAMILY if key in material), "plaster")
    grey = 0.55 + 0.35 * (zlib.crc32(material.encode()) % 100) / 100.0
    return (pattern, (grey, grey * 0.97, grey * 0.92), 0.8, 1.0)


def surface_look(material: str, room_kind: str | None = None, seed: int = 0, key: object = "") -> Look:
    """The look of a surface of acoustic `material` in a room of `room_kind`, in plan `seed`.

    `key` tells surfaces of one plan apart (a room index, a rug index) so they need not share
    a texture variant or a paint; the result is a pure function of the arguments.
    """
    pattern, colour, rough, period = _family(material)
    style = ROOM_STYLE.get(room_kind or "", {})
    h = _salt(seed, material, room_kind, key)
    if pattern in PAINTED and style:
        colour = style["paint"][h % len(style["paint"])]
    if material == "linoleum_on_concrete" and style:
        pattern = style["lino"]
    return Look(pattern, h % 4, colour, rough, period)


def is_soft(material: str) -> bool:
    """Whether a surface of `material` is drawn (and absorbs) as carpet or cloth."""
    return _family(material)[0] in SOFT_PATTERNS


def room_floor(material: str, room_kind: str, hard: tuple[str, ...], pick: int) -> str:
    """The floor a room of `room_kind` gets when `material` was drawn for it: wet rooms
    (kitchens, bathrooms) never keep a soft floor; they get `hard[pick % len(hard)]` instead."""
    if room_kind in WET_ROOMS and is_soft(material):
        return hard[pick % len(hard)]
    return material


def furniture_look(kind: str, material: str, seed: int = 0, key: object = "") -> Look:
    """Upholstered furniture looks like its (absorbing) cover; the rest by kind."""
    if kind in FURNITURE_LOOKS and _family(material)[0] in ("wood", "plaster"):
        pattern, colour, rough = FURNITURE_LOOKS[kind]
        return Look(pattern, _salt(seed, kind, key) % 4, colour, rough, 1.0)
    return surface_look(material, None, seed, key)
