"""Door articulation geometry and conventions (no robot): the hinge angle follows `Door`."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
import sapien

from echo_data.floorplan import Door
from echo_data.scene.articulated import DOOR_FLOOR_GAP, DOOR_MASS, build_door
from echo_data.scene.door_handle import HANDLE_EDGE_OFFSET, door_handle_world

_SCENES: list[sapien.Scene] = []  # a scene must outlive its articulations (dangling links segfault)


def physics_scene() -> sapien.Scene:
    scene = sapien.Scene([sapien.physx.PhysxCpuSystem()])
    scene.set_timestep(0.01)
    _SCENES.append(scene)
    return scene


def make_door(closed_yaw: float = math.pi / 2, open_sign: float = 1.0, angle: float = 0.0) -> Door:
    return Door(
        index=3, doorway=0, hinge=(1.0, 2.0), closed_yaw=closed_yaw, open_sign=open_sign, width=0.9,
        thickness=0.04, height=2.0, max_angle=1.9, open_threshold=1.3, angle=angle, handle_height=1.0,
        swing_room=0, material="wooden_door",
    )


def leaf_point(art: sapien.physx.PhysxArticulation, local: list[float]) -> np.ndarray:
    m = art.links[1].entity_pose.to_transformation_matrix()
    return m[:3, :3] @ np.asarray(local) + m[:3, 3]


@pytest.mark.parametrize("closed_yaw", [0.0, math.pi / 2, math.pi, -math.pi / 2])
@pytest.mark.parametrize("open_sign", [1.0, -1.0])
def test_free_edge_follows_door_convention(closed_yaw: float, open_sign: float) -> None:
    door = make_door(closed_yaw, open_sign)
    art = build_door(physics_scene(), door)
    for q in (0.0, 0.6, math.pi / 2):
        art.set_qpos(np.array([q], dtype=np.float32))
        edge = leaf_point(art, [door.width, 0.0, 0.0])
        assert np.allclose(edge[:2], door.free_edge(q), atol=1e-4), (q, edge, door.free_edge(q))


def test_limits_initial_angle_and_mass() -> None:
    door = make_door(angle=0.4)
    art = build_door(physics_scene(), door)
    assert art.dof == 1
    assert np.allclose(art.qlimits[0], [0.0, door.max_angle])
    assert art.qpos[0] == pytest.approx(0.4, abs=1e-6)
    assert art.links[1].mass == pytest.approx(DOOR_MASS, rel=0.1)
    assert art.root.entity_pose.p[:2] == pytest.approx(door.hinge, abs=1e-6)


def test_handles_on_both_faces_near_free_edge() -> None:
    door = make_door(closed_yaw=0.0, angle=0.7)
    art = build_door(physics_scene(), door)
    shapes = art.links[1].collision_shapes
    leaf_frame = art.links[1].entity_pose
    centres = [leaf_frame * s.local_pose for s in shapes]
    for face in (1.0, -1.0):
        want = door_handle_world(door, door.angle, face)
        dist = min(np.linalg.norm(c.p - want) for c in centres)
        assert dist < 1e-4, f"no handle bar at {want}"
        # the bar protrudes from its face and sits HANDLE_EDGE_OFFSET from the free edge
        along = want[:2] - np.asarray(door.hinge)
        yaw = door.leaf_yaw()
        assert along @ [math.cos(yaw), math.sin(yaw)] == pytest.approx(door.width - HANDLE_EDGE_OFFSET)
        normal = along @ [-math.sin(yaw), math.cos(yaw)]
        assert face * normal > door.thickness / 2.0 + 0.03
        assert want[2] == pytest.approx(door.handle_height)


def test_leaf_clears_the_floor() -> None:
    art = build_door(physics_scene(), make_door())
    lows = []
    for s in art.links[1].collision_shapes:
        pose = art.links[1].entity_pose * s.local_pose
        lows.append(pose.p[2] - s.half_size[2])
    assert min(lows) >= DOOR_FLOOR_GAP - 1e-6 >= 0.01


def test_released_door_stays_where_left() -> None:
    scene = physics_scene()
    art = build_door(scene, make_door(angle=0.5))
    art.set_qvel(np.array([1.0], dtype=np.float32))  # a shove
    for _ in range(150):
        scene.step()
    after_shove = float(art.qpos[0])
    assert 0.55 < after_shove < 1.0  # it moved, then friction and damping stopped it
    assert abs(float(art.qvel[0])) < 1e-3
    for _ in range(200):
        scene.step()
    assert float(art.qpos[0]) == pytest.approx(after_shove, abs=1e-3)


def test_joint_limit_stops_the_leaf() -> None:
    scene = physics_scene()
    door = make_door(angle=1.7)
    art = build_door(scene, door)
    art.set_qvel(np.array([3.0], dtype=np.float32))
    for _ in range(100):
        scene.step()
    assert float(art.qpos[0]) <= door.max_angle + 0.02
    art.set_qpos(np.array([0.2], dtype=np.float32))
    art.set_qvel(np.array([-3.0], dtype=np.float32))
    for _ in range(100):
        scene.step()
    assert float(art.qpos[0]) >= -0.02


def _static_plan_bodies(scene: sapien.Scene, plan) -> None:
    """Walls, furniture and floor of a plan as one static body (what the world builder adds)."""
    b = scene.create_actor_builder()
    for w in plan.walls:
        fp = w.footprint
        b.add_box_collision(
            pose=sapien.Pose([*fp.center, w.height / 2.0]), half_size=[fp.size[0] / 2.0, fp.size[1] / 2.0, w.height / 2.0]
        )
    for f in plan.furniture:
        b.add_box_collision(
            pose=sapien.Pose([*f.center, f.size[2] / 2.0]), half_size=[f.size[0] / 2.0, f.size[1] / 2.0, f.size[2] / 2.0]
        )
    b.add_box_collision(pose=sapien.Pose([0.0, 0.0, -0.05]), half_size=[100.0, 100.0, 0.05])
    b.build_static(name="static")


@pytest.mark.parametrize("seed", [0, 1])
def test_generated_doors_swing_their_full_range_without_jamming(seed: int) -> None:
    """In generated apartments each leaf clears walls and floor: a soft drive takes it to both limits."""
    from echo_data.recipe import Recipe
    from echo_data.scene.generate import generate_floorplan

    plan = generate_floorplan(Recipe(name="t", scene={"door_probability": 1.0}), np.random.default_rng(seed))
    assert plan.doors
    scene = physics_scene()
    _static_plan_bodies(scene, plan)
    doors = [build_door(scene, d) for d in plan.doors]
    scene.step()
    for c in scene.get_contacts():  # closed leaves touch nothing
        assert all(p.separation > -1e-3 for p in c.points)
    for target, expect in ((3.0, "max"), (-1.0, "min")):
        for art in doors:
            art.active_joints[0].set_drive_properties(200.0, 50.0)
            art.active_joints[0].set_drive_target(target)
        for _ in range(250):
            scene.step()
        for art, door in zip(doors, plan.doors):
            want = door.max_angle if expect == "max" else 0.0
            assert float(art.qpos[0]) == pytest.approx(want, abs=0.02), (door.index, expect)


def test_door_open_success_needs_threshold_and_rest() -> None:
    from types import SimpleNamespace

    from echo_data.floorplan import FloorPlan
    from echo_data.skills.success import door_open_success

    door = dataclasses.replace(make_door(angle=0.0), index=0)  # plan.doors[i].index == i
    scene = physics_scene()
    art = build_door(scene, door)
    world = SimpleNamespace(plan=FloorPlan(0, (), (), (), (door,), (), (), ()), handles=SimpleNamespace(doors=[art]))
    assert not door_open_success(world, 0)  # closed
    art.set_qpos(np.array([door.open_threshold + 0.05], dtype=np.float32))
    art.set_qvel(np.array([0.8], dtype=np.float32))
    assert not door_open_success(world, 0)  # open enough but still swinging
    for _ in range(200):
        scene.step()
    assert door_open_success(world, 0)
    art.set_qpos(np.array([door.open_threshold - 0.02], dtype=np.float32))
    art.set_qvel(np.zeros(1, dtype=np.float32))
    assert not door_open_success(world, 0)  # at rest, just short of the threshold
