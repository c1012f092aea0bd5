"""Household objects: declared sizes match the physics bodies, they rest where placed, fit the gripper."""

from __future__ import annotations

import math

import numpy as np
import pytest
import sapien

from echo_data.floorplan import PlacedObject
from echo_data.robot.robot import GRIPPER_OPEN
from echo_data.scene.bodies import build_object
from echo_data.scene.objects import (
    CATEGORIES,
    MAX_TARGET_GRASP_WIDTH,
    SIZE_RANGES,
    TARGET_CATEGORIES,
    instance_scale,
    object_mass,
    object_size,
)


def test_every_category_is_distinct_and_sized() -> None:
    sizes = {c: object_size(c) for c in CATEGORIES}
    assert len(set(sizes.values())) == len(CATEGORIES)
    sx, sy, sz = object_size("phone")
    assert (sx, sy, sz) == pytest.approx((0.15, 0.07, 0.015))
    # targets are taken across their narrow side by a gripper opening at most GRIPPER_OPEN
    for c in TARGET_CATEGORIES:
        assert min(object_size(c)[:2]) <= GRIPPER_OPEN - 0.015, c
    with pytest.raises(KeyError):
        object_size("piano")


def test_instance_sizes_vary_within_range_and_keep_targets_graspable() -> None:
    for c in CATEGORIES:
        lo, hi = SIZE_RANGES[c]
        scales = {instance_scale(c, f"{c}_0", seed) for seed in range(200)}
        assert min(scales) >= lo and max(scales) <= hi, c
        if hi == lo:
            continue  # a category kept at its base size
        assert len(scales) > 50, c
        assert max(scales) - min(scales) > 0.8 * (hi - lo), c  # the range is used
        assert instance_scale(c, f"{c}_0", 5) == instance_scale(c, f"{c}_0", 5)
        if c in TARGET_CATEGORIES:  # the narrow side at the largest size still fits the gripper
            assert min(object_size(c, hi)[:2]) <= MAX_TARGET_GRASP_WIDTH + 1e-9, c
    assert MAX_TARGET_GRASP_WIDTH <= GRIPPER_OPEN - 0.015 + 1e-9


@pytest.mark.parametrize("yaw,size", [(0.0, "base"), (0.7, "base"), (0.0, "low"), (0.7, "high")])
def test_bodies_match_sizes_and_rest_in_place(yaw: float, size: str) -> None:
    scene = sapien.Scene([sapien.physx.PhysxCpuSystem()])
    scene.set_timestep(0.01)
    ground = scene.create_actor_builder()
    ground.add_box_collision(half_size=[5.0, 5.0, 0.05])
    ground.set_initial_pose(sapien.Pose([0.0, 0.0, -0.05]))
    ground.build_static(name="floor")
    placed = {}
    scale = {c: {"base": 1.0, "low": SIZE_RANGES[c][0], "high": SIZE_RANGES[c][1]}[size] for c in CATEGORIES}
    for i, c in enumerate(CATEGORIES):
        sz = object_size(c, scale[c])[2]
        o = PlacedObject(i, f"{c}_0", c, (0.4 * i - 1.6, 0.5, sz / 2.0), yaw, 0, c in TARGET_CATEGORIES, scale[c])
        placed[c] = (o, build_object(scene, o))
    for _ in range(100):
        scene.step()
    for c, (o, entity) in placed.items():
        body = entity.find_component_by_type(sapien.physx.PhysxRigidDynamicComponent)
        assert entity.name == o.name
        assert body.mass == pytest.approx(object_mass(c, scale[c]), rel=0.02), c
        # at rest exactly where the plan put it (no drop, no slide, no tip)
        assert np.asarray(entity.pose.p) == pytest.approx(o.position, abs=1e-3), c
        assert np.linalg.norm(body.linear_velocity) < 1e-3
        # the axis-aligned bounds of the collision shapes equal the declared size (rotated by yaw)
        lo, hi = body.compute_global_aabb_tight()
        sx, sy, sz = object_size(c, scale[c])
        cy, sn = abs(math.cos(yaw)), abs(math.sin(yaw))
        ext = hi - lo
        assert ext[2] == pytest.approx(sz, abs=2e-3), c
        if c in ("phone", "box", "book"):  # plain boxes: the rotated footprint is exact
            assert ext[0] == pytest.approx(sx * cy + sy * sn, abs=2e-3), c
            assert ext[1] == pytest.approx(sx * sn + sy * cy, abs=2e-3), c
        else:
            assert max(ext[0], ext[1]) <= math.hypot(sx, sy) + 2e-3, c
        assert (lo[2] + hi[2]) / 2.0 == pytest.approx(o.position[2], abs=2e-3), c
