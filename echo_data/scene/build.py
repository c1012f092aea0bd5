"""SAPIEN construction of a floor plan: floor, walls with lintels, furniture, rugs and curtains
(visual only), objects, doors, faucets.

Static geometry is plain boxes (exactly the plan's footprints, so navigation, acoustics and
physics agree); colours depend on the material / kind so the head camera sees informative
images. Dynamic objects, doors and faucets come from `echo_data.scene.objects` and
`echo_data.scene.articulated`. Works in physics-only scenes too (no visuals then).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import sapien

from echo_data.recipe import Recipe
from echo_data.scene.articulated import WaterStream, build_door, build_faucet, has_render
from echo_data.scene.floorplan import FloorPlan, Furniture
from echo_data.scene.objects import build_object

FLOOR_THICKNESS = 0.1
# Static shapes: moderate friction (objects slide a little when pushed, not like ice).
STATIC_FRICTION = (0.8, 0.6, 0.0)

MATERIAL_COLOURS: dict[str, tuple[float, float, float]] = {
    # walls
    "plasterboard": (0.93, 0.92, 0.88),
    "brickwork": (0.72, 0.42, 0.33),
    "rough_concrete": (0.62, 0.62, 0.6),
    "gypsum_board": (0.9, 0.9, 0.92),
    "wooden_lining": (0.7, 0.55, 0.38),
    "ceramic_tiles": (0.85, 0.9, 0.92),
    # floors
    "linoleum_on_concrete": (0.55, 0.6, 0.52),
    "carpet_cotton": (0.58, 0.45, 0.45),
    "carpet_thin": (0.45, 0.5, 0.62),
    "audience_floor": (0.62, 0.48, 0.32),
    "concrete_floor": (0.6, 0.6, 0.6),
    "marble_floor": (0.88, 0.88, 0.86),
    "wooden_door": (0.55, 0.38, 0.22),
}
FURNITURE_COLOURS: dict[str, tuple[float, float, float]] = {
    "table": (0.62, 0.45, 0.26),
    "counter": (0.55, 0.55, 0.5),
    "shelf": (0.48, 0.33, 0.2),
    "cabinet": (0.66, 0.5, 0.34),
    "sofa": (0.3, 0.42, 0.62),
    "bed": (0.8, 0.66, 0.74),
    "sink_cabinet": (0.92, 0.92, 0.95),
}
FURNISHING_COLOURS: dict[str, tuple[float, float, float]] = {
    "carpet_tufted_9m": (0.55, 0.2, 0.22),
    "carpet_1.35_kg_m2": (0.3, 0.35, 0.5),
    "carpet_hairy": (0.85, 0.8, 0.68),
    "carpet_6mm_open_cell_foam": (0.4, 0.5, 0.38),
    "curtains_cotton_0.5": (0.9, 0.86, 0.74),
    "curtains_densely_woven": (0.42, 0.5, 0.6),
    "curtains_fabric": (0.7, 0.58, 0.44),
    "curtains_velvet": (0.5, 0.15, 0.2),
}
BASIN_COLOUR = (0.75, 0.85, 0.92)
LINTEL_COLOUR_SCALE = 0.95


def _colour(name: str, table: dict[str, tuple[float, float, float]]) -> tuple[float, float, float]:
    """A fixed colour for known names, else a stable pseudo-random pastel from the name."""
    if name in table:
        return table[name]
    h = sum((i + 1) * ord(c) for i, c in enumerate(name))
    rng = np.random.default_rng(h)
    return tuple(float(v) for v in 0.45 + 0.45 * rng.random(3))  # type: ignore[return-value]


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
    colour: tuple[float, float, float] | None,
    physx_material: sapien.physx.PhysxMaterial,
    extra_visuals: list[tuple[tuple[float, float, float], tuple[float, float, float], tuple[float, float, float]]] = (),  # type: ignore[assignment]
) -> sapien.Entity:
    """A static box body; `extra_visuals` are (offset, half size, colour) visual-only boxes."""
    builder = scene.create_actor_builder()
    builder.add_box_collision(half_size=list(half), material=physx_material)
    if colour is not None:
        builder.add_box_visual(half_size=list(half), material=sapien.render.RenderMaterial(base_color=[*colour, 1.0], roughness=0.8))
        for off, vhalf, vcol in extra_visuals:
            builder.add_box_visual(
                pose=sapien.Pose(list(off)),
                half_size=list(vhalf),
                material=sapien.render.RenderMaterial(base_color=[*vcol, 1.0], roughness=0.3),
            )
    builder.set_initial_pose(sapien.Pose(list(centre)))
    return builder.build_static(name=name)


def _furniture_visual_extras(f: Furniture) -> list:
    """A basin inset on a sink cabinet (visual only: the lever's clearance is unaffected)."""
    if f.kind != "sink_cabinet":
        return []
    half = (max(f.size[0] / 2.0 - 0.1, 0.05), max(f.size[1] / 2.0 - 0.1, 0.05), 0.002)
    return [((0.0, 0.0, f.size[2] / 2.0 + 0.001), half, BASIN_COLOUR)]


def build_statics(scene: sapien.Scene, plan: FloorPlan, with_walls: bool = True) -> tuple[list[sapien.Entity], dict[int, sapien.Entity]]:
    """Floor, walls, lintels and furniture as static boxes; returns (all statics, furniture by index)."""
    visual = has_render(scene)
    mat = sapien.physx.PhysxMaterial(*STATIC_FRICTION)
    statics: list[sapien.Entity] = []
    b = plan.bounds
    # one floor slab per room (its own material colour) plus a thin base slab under everything
    fb = b.expanded(0.5)
    statics.append(
        _static_box(
            scene,
            "floor",
            ((fb.xmin + fb.xmax) / 2.0, (fb.ymin + fb.ymax) / 2.0, -FLOOR_THICKNESS / 2.0),
            ((fb.xmax - fb.xmin) / 2.0, (fb.ymax - fb.ymin) / 2.0, FLOOR_THICKNESS / 2.0),
            (0.35, 0.35, 0.35) if visual else None,
            mat,
            [
                (
                    (r.rect.center[0] - (fb.xmin + fb.xmax) / 2.0, r.rect.center[1] - (fb.ymin + fb.ymax) / 2.0, FLOOR_THICKNESS / 2.0 + 0.0005),
                    (r.rect.size[0] / 2.0, r.rect.size[1] / 2.0, 0.0005),
                    _colour(r.floor_material, MATERIAL_COLOURS),
                )
                for r in plan.rooms
            ]
            + [  # rugs and curtains: seen, heard (they absorb), never in the way
                (
                    (fu.footprint.center[0] - (fb.xmin + fb.xmax) / 2.0, fu.footprint.center[1] - (fb.ymin + fb.ymax) / 2.0, (fu.z[0] + fu.z[1]) / 2.0 + FLOOR_THICKNESS / 2.0),
                    (fu.footprint.size[0] / 2.0, fu.footprint.size[1] / 2.0, (fu.z[1] - fu.z[0]) / 2.0),
                    _colour(fu.material, FURNISHING_COLOURS),
                )
                for fu in plan.furnishings
            ],
        )
    )
    if with_walls:
        for k, w in enumerate(plan.walls):
            fp = w.footprint
            statics.append(
                _static_box(
                    scene,
                    f"wall_{k}",
                    (fp.center[0], fp.center[1], w.height / 2.0),
                    (fp.size[0] / 2.0, fp.size[1] / 2.0, w.height / 2.0),
                    _colour(w.material, MATERIAL_COLOURS) if visual else None,
                    mat,
                )
            )
        for dw in plan.doorways:
            t = next((w.thickness for w in plan.walls), 0.1)
            top = plan.wall_height
            if top - dw.height < 0.01:
                continue
            sx, sy = (dw.width / 2.0, t / 2.0) if dw.axis == "x" else (t / 2.0, dw.width / 2.0)
            colour = tuple(c * LINTEL_COLOUR_SCALE for c in _colour(plan.rooms[max(dw.rooms)].wall_material, MATERIAL_COLOURS))
            statics.append(
                _static_box(
                    scene,
                    f"lintel_{dw.index}",
                    (dw.center[0], dw.center[1], (dw.height + top) / 2.0),
                    (sx, sy, (top - dw.height) / 2.0),
                    colour if visual else None,  # type: ignore[arg-type]
                    mat,
                )
            )
    furniture: dict[int, sapien.Entity] = {}
    for f in plan.furniture:
        e = _static_box(
            scene,
            f"furniture_{f.index}_{f.kind}",
            (f.center[0], f.center[1], f.size[2] / 2.0),
            (f.size[0] / 2.0, f.size[1] / 2.0, f.size[2] / 2.0),
            _colour(f.kind, FURNITURE_COLOURS) if visual else None,
            mat,
            _furniture_visual_extras(f),
        )
        furniture[f.index] = e
        statics.append(e)
    return statics, furniture


def build_scene(scene: sapien.Scene, plan: FloorPlan, recipe: Recipe) -> SceneHandles:
    """Build the whole apartment of `plan` into `scene`; deterministic per plan.

    `recipe` is accepted for the interface (physics rates live on the scene); nothing in the
    geometry depends on it beyond what the plan already holds.
    """
    del recipe
    handles = SceneHandles()
    handles.statics, handles.furniture = build_statics(scene, plan)
    for obj in plan.objects:
        handles.objects[obj.name] = build_object(scene, obj)
    for door in plan.doors:
        handles.doors.append(build_door(scene, door))
    for fc in plan.faucets:
        cabinet = plan.furniture[fc.furniture]
        handles.faucets.append(build_faucet(scene, fc, cabinet))
        handles.water.append(WaterStream(scene, fc, bottom_z=cabinet.top_z + 0.003))
    return handles
