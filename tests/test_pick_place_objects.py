"""Household objects: declared sizes match the physics bodies, they rest where placed, fit the gripper."""

from __future__ import annotations

import math

import numpy as np
import pytest
import sapien

from echo_data.robot.robot import GRIPPER_OPEN
from echo_data.scene.floorplan import PlacedObject
from echo_data.scene.objects import CATEGORIES, TARGET_CATEGORIES, build_object, object_mass, object_size


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


@pytest.mark.parametrize("yaw", [0.0, 0.7])
def test_bodies_match_sizes_and_rest_in_place(yaw: float) -> None:
    scene = sapien.Scene([sapien.physx.PhysxCpuSystem()])
    scene.set_timestep(0.01)
    ground = scene.create_actor_builder()
    ground.add_box_collision(half_size=[5.0, 5.0, 0.05])
    ground.set_initial_pose(sapien.Pose([0.0, 0.0, -0.05]))
    ground.build_static(name="floor")
    placed = {}
    for i, c in enumerate(CATEGORIES):
        sz = object_size(c)[2]
        o = PlacedObject(i, f"{c}_0", c, (0.4 * i - 1.6, 0.5, sz / 2.0), yaw, 0, c in TARGET_CATEGORIES)
        placed[c] = (o, build_object(scene, o))
    for _ in range(100):
        scene.step()
    for c, (o, entity) in placed.items():
        body = entity.find_component_by_type(sapien.physx.PhysxRigidDynamicComponent)
        assert entity.name == o.name
        assert body.mass == pytest.approx(object_mass(c), rel=0.02), c
        # at rest exactly where the plan put it (no drop, no slide, no tip)
        assert np.asarray(entity.pose.p) == pytest.approx(o.position, abs=1e-3), c
        assert np.linalg.norm(body.linear_velocity) < 1e-3
        # the axis-aligned bounds of the collision shapes equal the declared size (rotated by yaw)
        lo, hi = body.compute_global_aabb_tight()
        sx, sy, sz = object_size(c)
        cy, sn = abs(math.cos(yaw)), abs(math.sin(yaw))
        ext = hi - lo
        assert ext[2] == pytest.approx(sz, abs=2e-3), c
        if c in ("phone", "box", "book"):  # plain boxes: the rotated footprint is exact
            assert ext[0] == pytest.approx(sx * cy + sy * sn, abs=2e-3), c
            assert ext[1] == pytest.approx(sx * sn + sy * cy, abs=2e-3), c
        else:
            assert max(ext[0], ext[1]) <= math.hypot(sx, sy) + 2e-3, c
        assert (lo[2] + hi[2]) / 2.0 == pytest.approx(o.position[2], abs=2e-3), c
