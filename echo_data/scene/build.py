"""SAPIEN construction of a floor plan: floor, walls with lintels, furniture, rugs and curtains
(visual only), objects, doors, faucets.

Static geometry is plain boxes (exactly the plan's footprints, so navigation, acoustics and
physics agree), drawn as textured meshes whose look follows the surface's acoustic material and
room kind (`echo_data.scene.surfaces`), so what the camera sees is what the ears hear. Dynamic
objects, doors and faucets come from `echo_data.scene.objects` and `echo_data.scene.articulated`. Works in physics-only scenes too (no visuals then).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field, replace

import sapien

from echo_data.floorplan import FloorPlan, Furniture, Rect, Room
from echo_data.recipe import Recipe
from echo_data.scene import meshes, textures
from echo_data.scene.articulated import (
    WaterStream,
    build_door,
    build_faucet,
    has_render,
)
from echo_data.scene.bodies import build_object
from echo_data.scene.surfaces import Look, furniture_look, surface_look

FLOOR_THICKNESS = 0.1
# Static shapes: moderate friction (objects slide a little when pushed, not like ice).
STATIC_FRICTION = (0.8, 0.6, 0.0)
BASE_SLAB = Look("concrete", 0, (0.35, 0.35, 0.35), 0.9, 2.0)
BASIN = Look("plain", 0, (0.75, 0.85, 0.92), 0.1, 1.0)
LINTEL_COLOUR_SCALE = 0.95

# One visual box: (offset from the body, half size, look)
Visual = tuple[tuple[float, float, float], tuple[float, float, float], Look]


def render_material(look: Look, flat: bool) -> sapien.render.RenderMaterial:
    """The SAPIEN material of a look: textured, or (flat) its colour alone."""
    return textures.render_material("plain" if flat else look.pattern, look.variant, look.colour, look.roughness)


def add_visual_box(
    body: sapien.render.RenderBodyComponent, offset: Sequence[float], half: Sequence[float], look: Look, flat: bool
) -> None:
    """A box visual whose texture repeats at the look's real size (SAPIEN's own box stretches it)."""
    mesh = meshes.box(tuple(float(h) for h in half), look.period)
    shape = sapien.render.RenderShapeTriangleMesh(*mesh, render_material(look, flat))
    shape.local_pose = sapien.Pose(list(offset))
    body.attach(shape)


@dataclass
class SceneHandles:
    """What the rest of the pipeline needs from a built scene."""

    objects: dict[str, sapien.Entity] = field(default_factory=dict)
    doors: list[sapien.physx.PhysxArticulation] = field(default_factory=list)  # index = Door.index
    faucets: list[sapien.physx.PhysxArticulation] = field(default_factory=list)  # index = Faucet.index
    water: list[WaterStream] = field(default_factory=list)  # index = Faucet.index
    statics: list[sapien.Entity] = field(default_factory=list)  # floor, walls, lintels, furniture
    furniture: dict[int, sapien.Entity] = field(default_factory=dict)  # by Furniture.index

    def update(self) -> None:
        """Let the water follow the levers; call after physics steps."""
        for art, stream in zip(self.faucets, self.water):
            stream.update(float(art.get_qpos()[0]))

    def door_angles(self) -> dict[int, float]:
        """Current hinge angle of every door."""
        return {i: float(a.get_qpos()[0]) for i, a in enumerate(self.doors)}

    def faucet_angles(self) -> dict[int, float]:
        """Current lever angle of every faucet."""
        return {i: float(a.get_qpos()[0]) for i, a in enumerate(self.faucets)}


def _static_box(
    scene: sapien.Scene,
    name: str,
    centre: tuple[float, float, float],
    half: tuple[float, float, float],
    physx_material: sapien.physx.PhysxMaterial,
    visuals: list[Visual] | None,
    flat: bool = False,
) -> sapien.Entity:
    """A static box body (collision exactly `half`) drawn as `visuals` (None: physics only)."""
    builder = scene.create_actor_builder()
    builder.add_box_collision(half_size=list(half), material=physx_material)
    builder.set_physx_body_type("static")
    entity = builder.build_entity()  # unlike build(), leaves pose and scene to the caller
    entity.name = name
    entity.pose = sapien.Pose(list(centre))
    if visuals:
        body = sapien.render.RenderBodyComponent()
        for off, vhalf, look in visuals:
            add_visual_box(body, off, vhalf, look, flat)
        entity.add_component(body)
    scene.add_entity(entity)
    return entity


def _furniture_visuals(f: Furniture, seed: int) -> list[Visual]:
    """The furniture box in its look; a basin inset on a sink cabinet (visual only: the lever's
    clearance is unaffected)."""
    out: list[Visual] = [((0.0, 0.0, 0.0), (f.size[0] / 2.0, f.size[1] / 2.0, f.size[2] / 2.0), furniture_look(f.kind, f.material, seed, f.index))]
    if f.kind == "sink_cabinet":
        half = (max(f.size[0] / 2.0 - 0.1, 0.05), max(f.size[1] / 2.0 - 0.1, 0.05), 0.002)
        out.append(((0.0, 0.0, f.size[2] / 2.0 + 0.001), half, BASIN))
    return out


def _room_at(plan: FloorPlan, x: float, y: float) -> Room | None:
    """The room whose rectangle holds (x, y), or None (outside the flat)."""
    return next((r for r in plan.rooms if r.rect.xmin <= x <= r.rect.xmax and r.rect.ymin <= y <= r.rect.ymax), None)


def _wall_visuals(plan: FloorPlan, fp: Rect, height: float, material: str, key: object, scale: float = 1.0) -> list[Visual]:
    """A wall drawn as two half-thickness layers, each in the style of the room it faces
    (paint follows the room kind; the wall material, and so its absorption, is the plan's)."""
    cx, cy = fp.center
    sx, sy = fp.size[0] / 2.0, fp.size[1] / 2.0
    out: list[Visual] = []
    along_x = sx >= sy
    for sign in (-1.0, 1.0):
        off = (0.0, sign * sy / 2.0) if along_x else (sign * sx / 2.0, 0.0)
        probe = (cx, cy + sign * (sy + 0.05)) if along_x else (cx + sign * (sx + 0.05), cy)
        room = _room_at(plan, *probe)
        look = surface_look(material, room.kind if room else None, plan.seed, plan.space_of(room.index) if room else key)  # one paint per space
        if scale != 1.0:
            r, g, b = (c * scale for c in look.colour)
            look = replace(look, colour=(r, g, b))
        half = (sx, sy / 2.0, height / 2.0) if along_x else (sx / 2.0, sy, height / 2.0)
        out.append(((off[0], off[1], 0.0), half, look))
    return out


def build_statics(
    scene: sapien.Scene, plan: FloorPlan, with_walls: bool = True, flat: bool = False
) -> tuple[list[sapien.Entity], dict[int, sapien.Entity]]:
    """Floor, walls, lintels and furniture as static boxes; returns (all statics, furniture by index).

    Looks come from `echo_data.scene.surfaces` (the surface's acoustic material and room kind);
    `flat` draws each surface in its colour alone."""
    visual = has_render(scene)
    mat = sapien.physx.PhysxMaterial(*STATIC_FRICTION)
    statics: list[sapien.Entity] = []
    b = plan.bounds
    # one floor slab per room (its own material) plus a thin base slab under everything
    fb = b.expanded(0.5)
    ox, oy = (fb.xmin + fb.xmax) / 2.0, (fb.ymin + fb.ymax) / 2.0
    floor_visuals: list[Visual] = [((0.0, 0.0, 0.0), ((fb.xmax - fb.xmin) / 2.0, (fb.ymax - fb.ymin) / 2.0, FLOOR_THICKNESS / 2.0), BASE_SLAB)]
    floor_visuals += [
        (
            (r.rect.center[0] - ox, r.rect.center[1] - oy, FLOOR_THICKNESS / 2.0 + 0.0005),
            (r.rect.size[0] / 2.0, r.rect.size[1] / 2.0, 0.0005),
            surface_look(r.floor_material, r.kind, plan.seed, plan.space_of(r.index)),  # one floor per space
        )
        for r in plan.rooms
    ]
    floor_visuals += [  # rugs and curtains: seen and heard as what they are, never in the way
        (
            (fu.footprint.center[0] - ox, fu.footprint.center[1] - oy, (fu.z[0] + fu.z[1]) / 2.0 + FLOOR_THICKNESS / 2.0),
            (fu.footprint.size[0] / 2.0, fu.footprint.size[1] / 2.0, (fu.z[1] - fu.z[0]) / 2.0),
            surface_look(fu.material, None, plan.seed, ("furnishing", fu.index)),
        )
        for fu in plan.furnishings
    ]
    statics.append(
        _static_box(
            scene, "floor", (ox, oy, -FLOOR_THICKNESS / 2.0),
            ((fb.xmax - fb.xmin) / 2.0, (fb.ymax - fb.ymin) / 2.0, FLOOR_THICKNESS / 2.0),
            mat, floor_visuals if visual else None, flat,
        )
    )
    if with_walls:
        for k, w in enumerate(plan.walls):
            fp = w.footprint
            statics.append(
                _static_box(
                    scene, f"wall_{k}", (fp.center[0], fp.center[1], w.height / 2.0),
                    (fp.size[0] / 2.0, fp.size[1] / 2.0, w.height / 2.0),
                    mat, _wall_visuals(plan, fp, w.height, w.material, k) if visual else None, flat,
                )
            )
        for dw in plan.doorways:
            t = next((w.thickness for w in plan.walls), 0.1)
            top = plan.wall_height
            if top - dw.height < 0.01:
                continue
            sx, sy = (dw.width / 2.0, t / 2.0) if dw.axis == "x" else (t / 2.0, dw.width / 2.0)
            fp = Rect(dw.center[0] - sx, dw.center[1] - sy, dw.center[0] + sx, dw.center[1] + sy)
            material = plan.rooms[max(dw.rooms)].wall_material
            statics.append(
                _static_box(
                    scene, f"lintel_{dw.index}", (dw.center[0], dw.center[1], (dw.height + top) / 2.0),
                    (sx, sy, (top - dw.height) / 2.0),
                    mat, _wall_visuals(plan, fp, top - dw.height, material, ("lintel", dw.index), LINTEL_COLOUR_SCALE) if visual else None, flat,
                )
            )
    furniture: dict[int, sapien.Entity] = {}
    for f in plan.furniture:
        e = _static_box(
            scene, f"furniture_{f.index}_{f.kind}", (f.center[0], f.center[1], f.size[2] / 2.0),
            (f.size[0] / 2.0, f.size[1] / 2.0, f.size[2] / 2.0),
            mat, _furniture_visuals(f, plan.seed) if visual else None, flat,
        )
        furniture[f.index] = e
        statics.append(e)
    return statics, furniture


def build_scene(scene: sapien.Scene, plan: FloorPlan, recipe: Recipe) -> SceneHandles:
    """Build the whole apartment of `plan` into `scene`; deterministic per plan.

    Only the look depends on `recipe` (`scene.look`); the geometry is the plan's.
    """
    flat = recipe.scene.look == "flat"
    handles = SceneHandles()
    handles.statics, handles.furniture = build_statics(scene, plan, flat=flat)
    for obj in plan.objects:
        handles.objects[obj.name] = build_object(scene, obj, plan.seed, flat)
    for door in plan.doors:
        handles.doors.append(build_door(scene, door))
    for fc in plan.faucets:
        cabinet = plan.furniture[fc.furniture]
        handles.faucets.append(build_faucet(scene, fc, cabinet))
        handles.water.append(WaterStream(scene, fc, bottom_z=cabinet.top_z + 0.003))
    return handles
