"""Rigid household objects as SAPIEN bodies: collision from the catalogue's primitives
(`echo_data.scene.objects`), visuals as textured meshes in each instance's look."""

from __future__ import annotations

import math

import numpy as np
import sapien

from echo_data.floorplan import PlacedObject
from echo_data.scene import meshes, textures
from echo_data.scene.objects import CATEGORIES, MODELS, Part, instance_look, object_mass, part_volume, scaled_part

# Objects are grippy (rubber/plastic); the robot's finger pads are 2.0 (docs/SIMULATION_NOTES.md#grasping).
OBJECT_STATIC_FRICTION = 1.0
OBJECT_DYNAMIC_FRICTION = 0.8
OBJECT_RESTITUTION = 0.0
# Torsional friction (PhysX patch radius): a round object held at two points would otherwise
# swing freely about the jaw axis while the robot drives.
PATCH_RADIUS = 0.01
MIN_PATCH_RADIUS = 0.005


def _yaw_quat(yaw: float) -> list[float]:
    return [math.cos(yaw / 2.0), 0.0, 0.0, math.sin(yaw / 2.0)]


_Z_TO_Y = ((1.0, 0.0, 0.0), (0.0, 0.0, 1.0), (0.0, -1.0, 0.0))


def _visual_shape(p: Part, colour: tuple[float, float, float], variant: int, flat: bool) -> sapien.render.RenderShapeTriangleMesh:
    """One part as a textured mesh (UVs fitted once per face / around once)."""
    if p.kind == "box":
        mesh = meshes.box(tuple(p.dims), None)
    elif p.kind == "sphere":
        mesh = meshes.ellipsoid((p.dims[0],) * 3)
    else:
        mesh = meshes.cylinder(p.dims[0], p.dims[1])
        if p.kind == "ycyl":
            mesh = meshes.rotated(mesh, np.asarray(_Z_TO_Y))
    rough = 0.2 if p.pattern == "screen" else 0.6
    mat = textures.render_material("plain" if flat else p.pattern, variant, colour, rough)
    shape = sapien.render.RenderShapeTriangleMesh(*mesh, mat)
    shape.local_pose = sapien.Pose(list(p.center))
    return shape


def build_object(
    scene: sapien.Scene, obj: PlacedObject, seed: int = 0, flat: bool = False, mono: tuple[float, float, float] | None = None
) -> sapien.Entity:
    """Add `obj` to `scene` as a dynamic rigid body named `obj.name`, at rest at its pose.

    Collision is the model's primitives; visuals are textured meshes in the instance's look
    (`instance_look`; `flat`: one colour per part, no print; `mono`: every part in this one
    colour, shape alone — the visual probe's control). Visual shapes are added only when
    the scene has a render system (physics-only scenes for solvability checks work too).
    """
    model = MODELS.get(obj.category)
    if model is None:
        raise KeyError(f"unknown object category {obj.category!r}; known: {', '.join(CATEGORIES)}")
    try:
        scene.render_system  # noqa: B018 (raises without a render system)
        with_visuals = True
    except RuntimeError:
        with_visuals = False
    mat = sapien.physx.PhysxMaterial(OBJECT_STATIC_FRICTION, OBJECT_DYNAMIC_FRICTION, OBJECT_RESTITUTION)
    parts = [scaled_part(p, obj.scale) for p in model.parts]
    solid = [p for p in parts if p.collide]
    density = object_mass(obj.category, obj.scale) / sum(part_volume(p) for p in solid)
    # upright cylinders: SAPIEN cylinders lie along x; turn x -> z (about y by -90 deg), or x -> y (about z)
    to_z = sapien.Pose(q=[math.sqrt(0.5), 0.0, -math.sqrt(0.5), 0.0])
    to_y = sapien.Pose(q=[math.sqrt(0.5), 0.0, 0.0, math.sqrt(0.5)])
    builder = scene.create_actor_builder()
    for p in solid:
        at = sapien.Pose(p.center)
        if p.kind == "zcyl":
            at = at * to_z
        elif p.kind == "ycyl":
            at = at * to_y
        patch = {"patch_radius": PATCH_RADIUS, "min_patch_radius": MIN_PATCH_RADIUS}
        if p.kind == "box":
            builder.add_box_collision(at, p.dims, material=mat, density=density, **patch)
        elif p.kind == "sphere":
            builder.add_sphere_collision(at, p.dims[0], material=mat, density=density, **patch)
        else:
            builder.add_cylinder_collision(at, p.dims[0], p.dims[1], material=mat, density=density, **patch)
    builder.set_initial_pose(sapien.Pose(list(obj.position), _yaw_quat(obj.yaw)))
    entity = builder.build_entity()  # unlike build(), leaves pose and scene to the caller
    entity.name = obj.name
    entity.pose = sapien.Pose(list(obj.position), _yaw_quat(obj.yaw))
    if with_visuals:
        body_colour, variant = instance_look(obj.category, obj.name, seed)
        body = sapien.render.RenderBodyComponent()
        for p in parts:
            colour = mono if mono is not None else body_colour if p.body else p.color
            body.attach(_visual_shape(p, colour, variant, flat or mono is not None))
        entity.add_component(body)
    scene.add_entity(entity)
    return entity
