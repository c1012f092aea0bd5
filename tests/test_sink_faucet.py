"""Faucet articulation and water stream (no robot): the lever angle drives the water."""

from __future__ import annotations

import math
import os

import numpy as np
import pytest
import sapien

from echo_data.floorplan import Faucet, Furniture
from echo_data.scene.articulated import STATIC_CLEARANCE, WaterStream, build_faucet, lever_tip_world

_SCENES: list[sapien.Scene] = []  # a scene must outlive its articulations (dangling links segfault)

CABINET = Furniture(
    index=2, kind="sink_cabinet", room=0, center=(0.0, 0.0), size=(0.6, 1.0, 0.9), yaw=0.0,
    material="wooden_door", receptacle=False,
)


def physics_scene(with_cabinet: bool = True) -> sapien.Scene:
    scene = sapien.Scene([sapien.physx.PhysxCpuSystem()])
    scene.set_timestep(0.01)
    if with_cabinet:
        b = scene.create_actor_builder()
        sx, sy, h = CABINET.size
        b.add_box_collision(pose=sapien.Pose([*CABINET.center, h / 2.0]), half_size=[sx / 2.0, sy / 2.0, h / 2.0])
        b.build_static(name="cabinet")
    _SCENES.append(scene)
    return scene


def make_faucet(angle: float = 1.2, yaw: float = 0.0, pivot_z: float = 1.0) -> Faucet:
    return Faucet(
        index=0, furniture=2, pivot=(-0.2, 0.12, pivot_z), yaw=yaw, lever_length=0.15, open_angle=math.pi / 2,
        closed_tolerance=0.08, angle=angle, spout=(-0.05, 0.0, 0.98),
    )


def lever_tip(art: sapien.physx.PhysxArticulation, faucet: Faucet) -> np.ndarray:
    m = art.links[1].entity_pose.to_transformation_matrix()
    return m[:3, :3] @ np.array([faucet.lever_length, 0.0, 0.0]) + m[:3, 3]


@pytest.mark.parametrize("yaw", [0.0, math.pi / 2, -2.5])
def test_lever_follows_faucet_convention(yaw: float) -> None:
    faucet = make_faucet(yaw=yaw)
    art = build_faucet(physics_scene(), faucet, CABINET)
    assert art.qpos[0] == pytest.approx(faucet.angle, abs=1e-6)
    assert np.allclose(art.qlimits[0], [0.0, faucet.open_angle])
    for a in (0.0, 0.5, faucet.open_angle):
        art.set_qpos(np.array([a], dtype=np.float32))
        tip = lever_tip(art, faucet)
        assert np.allclose(tip, lever_tip_world(faucet, a), atol=1e-4)
        # counter-clockwise opens
        expect = (math.cos(yaw + a), math.sin(yaw + a))
        assert np.allclose((tip[:2] - faucet.pivot[:2]) / faucet.lever_length, expect, atol=1e-4)


def test_lever_too_close_to_counter_is_rejected() -> None:
    with pytest.raises(ValueError, match="counter top"):
        build_faucet(physics_scene(), make_faucet(pivot_z=CABINET.top_z + STATIC_CLEARANCE), CABINET)


def test_lever_moves_freely_over_its_range_above_the_cabinet() -> None:
    """A soft drive closes the lever fully: nothing jams it (clearance to the counter)."""
    scene = physics_scene()
    faucet = make_faucet(angle=math.pi / 2)
    art = build_faucet(scene, faucet, CABINET)
    joint = art.active_joints[0]
    joint.set_drive_properties(2.0, 0.2)
    joint.set_drive_target(-0.2)  # pushes into the lower limit
    angles = []
    for _ in range(200):
        scene.step()
        angles.append(float(art.qpos[0]))
    assert angles[0] > 1.5
    assert angles[-1] < 0.02
    assert angles[-1] > -0.02  # the limit holds
    assert all(b <= a + 1e-3 for a, b in zip(angles, angles[1:]))  # monotone closing


def test_released_lever_stays_where_left() -> None:
    scene = physics_scene()
    art = build_faucet(scene, make_faucet(angle=0.8), CABINET)
    for _ in range(100):
        scene.step()
    assert float(art.qpos[0]) == pytest.approx(0.8, abs=0.02)


def test_stream_follows_lever_angle() -> None:
    faucet = make_faucet()
    stream = WaterStream(physics_scene(with_cabinet=False), faucet, bottom_z=CABINET.top_z)
    assert stream.flowing and stream.radius > 0
    radii = []
    for a in np.linspace(0.0, faucet.open_angle, 25):
        stream.update(float(a))
        assert stream.flowing == (a > faucet.closed_tolerance)
        assert (stream.radius > 0) == stream.flowing
        radii.append(stream.radius)
    assert all(b >= a for a, b in zip(radii, radii[1:]))
    assert radii[-1] > radii[5] > 0
    stream.update(faucet.closed_tolerance * 0.5)
    assert not stream.flowing and stream.flow == 0.0 and stream.radius == 0.0


def test_stream_is_visual_only_and_hangs_under_the_spout() -> None:
    os.environ.setdefault("VK_ICD_FILENAMES", "/usr/share/vulkan/icd.d/lvp_icd.json")
    scene = sapien.Scene()  # with a render system
    _SCENES.append(scene)
    faucet = make_faucet(angle=1.2)
    stream = WaterStream(scene, faucet, bottom_z=CABINET.top_z)
    lo, hi = stream.visible_extent()
    assert lo[2] == pytest.approx(CABINET.top_z, abs=1e-3) and hi[2] == pytest.approx(faucet.spout[2], abs=1e-3)
    centre = (lo + hi) / 2.0
    assert centre[:2] == pytest.approx(faucet.spout[:2], abs=1e-3)
    assert (hi[0] - lo[0]) / 2.0 == pytest.approx(stream.radius, rel=0.05)
    assert stream.flowing
    for entity in scene.entities:
        if entity.name.startswith("water_"):
            assert entity.find_component_by_type(sapien.physx.PhysxRigidBaseComponent) is None
    stream.update(0.0)
    assert stream.visible_extent() is None
    shown = [e for e in scene.entities if e.name.startswith("water_") and e.pose.p[2] > -1.0]
    assert shown == []


@pytest.mark.parametrize("seed", [0, 3])
def test_generated_faucet_sweeps_its_range_clear_of_cabinet_and_walls(seed: int) -> None:
    from echo_data.recipe import Recipe
    from echo_data.scene.generate import generate_floorplan

    plan = generate_floorplan(Recipe(name="t"), np.random.default_rng(seed))
    faucet = plan.faucets[0]
    cabinet = plan.furniture[faucet.furniture]
    scene = physics_scene(with_cabinet=False)
    b = scene.create_actor_builder()
    for w in plan.walls:
        fp = w.footprint
        b.add_box_collision(
            pose=sapien.Pose([*fp.center, w.height / 2.0]), half_size=[fp.size[0] / 2.0, fp.size[1] / 2.0, w.height / 2.0]
        )
    sx, sy, h = cabinet.size
    b.add_box_collision(pose=sapien.Pose([*cabinet.center, h / 2.0]), half_size=[sx / 2.0, sy / 2.0, h / 2.0])
    b.build_static(name="static")
    art = build_faucet(scene, faucet, cabinet)
    stream = WaterStream(scene, faucet, bottom_z=cabinet.top_z)
    joint = art.active_joints[0]
    joint.set_drive_properties(2.0, 0.2)
    for target, want in ((2.0, faucet.open_angle), (-0.3, 0.0)):
        joint.set_drive_target(target)
        for _ in range(200):
            scene.step()
        stream.update(float(art.qpos[0]))
        assert float(art.qpos[0]) == pytest.approx(want, abs=0.02)
    assert not stream.flowing


def test_sink_closed_success_needs_lever_closed_and_water_off() -> None:
    from types import SimpleNamespace

    from echo_data.floorplan import FloorPlan
    from echo_data.skills.success import sink_closed_success

    faucet = make_faucet(angle=1.2)
    scene = physics_scene()
    art = build_faucet(scene, faucet, CABINET)
    stream = WaterStream(scene, faucet, bottom_z=CABINET.top_z)
    world = SimpleNamespace(
        plan=FloorPlan(0, (), (), (), (), (CABINET,), (faucet,), ()),
        handles=SimpleNamespace(faucets=[art], water=[stream]),
    )
    assert not sink_closed_success(world, 0) and stream.flowing
    art.set_qpos(np.array([faucet.closed_tolerance + 0.03], dtype=np.float32))
    assert not sink_closed_success(world, 0) and stream.flowing  # a trickle still runs
    art.set_qpos(np.array([faucet.closed_tolerance * 0.5], dtype=np.float32))
    assert sink_closed_success(world, 0) and not stream.flowing
