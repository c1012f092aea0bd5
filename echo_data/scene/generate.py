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

This module is the orchestration; the stages are `scene.structure` (rooms, walls, doorways,
doors), `scene.furniture` (furniture, faucet, objects) and `scene.soft_furnishings` (rugs,
curtains).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from echo_data import seeds
from echo_data.floorplan import (
    Door,
    FloorPlan,
    Furniture,
    Room,
)
from echo_data.recipe import Recipe
from echo_data.scene.furniture import (
    FURNITURE_SPECS,
    ROOM_FURNITURE,
    SINK_ROOMS,
    _make_faucet,
    _place_furniture,
    _room_connected,
    place_object,
)
from echo_data.scene.layouts import Layout, draw_family, draw_layout
from echo_data.scene.objects import instance_scale
from echo_data.scene.soft_furnishings import _furnish
from echo_data.scene.structure import (
    DOOR_CLEARANCE_DEPTH,
    DOOR_CLEARANCE_SIDE,
    DOOR_HINGE_SIDE_ROOM,
    DOORWAY_HEIGHT,
    INTERIOR_BELL_PROBABILITY,
    GenerationError,
    _assign_kinds,
    _assign_space_kinds,
    _doorway_zone,
    _make_door,
    _pick_doorway,
    _segments,
    _side_room,
    _spanning_doorways,
    _wall_pieces,
    _wide_openings,
    door_operation_zone,
    door_swing_zone,
)
from echo_data.scene.surfaces import room_floor

__all__ = ["GenerationError", "generate_floorplan", "generate_floorplan_from_seed"]  # the stages own the rest


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
    """One try at a floor plan of `family`, or None. Long because the order of its random draws
    is every plan's seed story: kept in one body so a change cannot reorder the draws."""
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
