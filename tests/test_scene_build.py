"""SAPIEN construction of generated plans: bodies, shapes, articulations, resting physics, top-down PNG."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import sapien
from PIL import Image

from echo_data.recipe import Recipe
from echo_data.scene.build import SceneHandles, build_scene
from echo_data.scene.generate import generate_floorplan
from echo_data.scene.sampling import sample_episode
from echo_data.sounds.library import SoundLibrary
from echo_data.viz.topdown import draw_topdown

RECIPE = Recipe(name="t", scene={"rooms": (3, 4), "door_probability": 1.0}, objects={"distractors": (3, 4)})


def _physics_scene() -> sapien.Scene:
    scene = sapien.Scene([sapien.physx.PhysxCpuSystem()])
    scene.set_timestep(1.0 / 100.0)
    return scene


@pytest.fixture(scope="module")
def built() -> tuple[sapien.Scene, SceneHandles, object]:
    plan = generate_floorplan(RECIPE, np.random.default_rng(3))
    scene = _physics_scene()
    return scene, build_scene(scene, plan, RECIPE), plan


def test_bodies_match_the_plan(built) -> None:  # type: ignore[no-untyped-def]
    scene, h, plan = built
    names = [e.name for e in scene.entities]
    assert sum(n.startswith("wall_") for n in names) == len(plan.walls)
    # a wide opening of one space (scene/layouts.py) runs to the ceiling: no lintel
    assert sum(n.startswith("lintel_") for n in names) == len(plan.doorways) - len(plan.open_doorways)
    assert len(h.furniture) == len(plan.furniture)
    assert set(h.objects) == {o.name for o in plan.objects} and len(h.objects) >= 3
    assert len(h.doors) == len(plan.doors) >= 2 and len(h.faucets) == len(h.water) == 1
    # furniture collision boxes are exactly the plan's footprints and heights
    for f in plan.furniture:
        body = h.furniture[f.index].find_component_by_type(sapien.physx.PhysxRigidStaticComponent)
        (shape,) = body.get_collision_shapes()
        assert np.allclose(shape.half_size, np.array(f.size) / 2.0, atol=1e-6)
        assert np.allclose(h.furniture[f.index].pose.p, [f.center[0], f.center[1], f.size[2] / 2.0], atol=1e-6)
    # lintels sit above the doorways, up to the ceiling
    for dw in (d for d in plan.doorways if d.index not in plan.open_doorways):
        lintel = next(e for e in scene.entities if e.name == f"lintel_{dw.index}")
        (shape,) = lintel.find_component_by_type(sapien.physx.PhysxRigidStaticComponent).get_collision_shapes()
        assert lintel.pose.p[2] - shape.half_size[2] == pytest.approx(dw.height, abs=1e-5)
        assert lintel.pose.p[2] + shape.half_size[2] == pytest.approx(plan.wall_height, abs=1e-5)


def test_world_rests_and_water_follows_the_lever(built) -> None:  # type: ignore[no-untyped-def]
    scene, h, plan = built
    for _ in range(50):
        scene.step()
    h.update()
    for o in plan.objects:
        assert np.linalg.norm(h.objects[o.name].pose.p - np.array(o.position)) < 0.01, o.name
    assert all(abs(a) < 1e-3 for a in h.door_angles().values())
    assert h.faucet_angles()[0] == pytest.approx(plan.faucets[0].angle, abs=1e-3)
    assert h.water[0].flowing
    h.faucets[0].set_qpos(np.zeros(1, dtype=np.float32))
    scene.step()
    h.update()
    assert not h.water[0].flowing


def test_build_is_deterministic() -> None:
    plan = generate_floorplan(RECIPE, np.random.default_rng(4))
    poses = []
    for _ in range(2):
        scene = _physics_scene()
        h = build_scene(scene, plan, RECIPE)
        for _ in range(20):
            scene.step()
        poses.append(np.concatenate([np.concatenate([e.pose.p, e.pose.q]) for e in h.objects.values()]))
    assert np.array_equal(poses[0], poses[1])


def test_topdown_png(tmp_path: Path) -> None:
    spec, _ = sample_episode(Recipe(name="t", setting="multi_event"), "train", 0, SoundLibrary.builtin())
    bare, full = tmp_path / "bare.png", tmp_path / "sub" / "full.png"
    draw_topdown(spec.plan, bare)
    path = [(spec.start[0], spec.start[1]), spec.events[0].source[:2]]
    draw_topdown(spec.plan, full, path=path, start=spec.start, events=spec.events)
    a, b = np.asarray(Image.open(bare).convert("RGB")), np.asarray(Image.open(full).convert("RGB"))
    assert a.shape == b.shape and a.shape[0] > 300 and a.shape[1] > 300
    assert len(np.unique(a.reshape(-1, 3), axis=0)) > 20  # rooms, walls, furniture in colour
    # the start disc and the path are drawn in green
    green = (b[..., 1] > 120) & (b[..., 0] < 90) & (b[..., 2] < 90)
    green_bare = (a[..., 1] > 120) & (a[..., 0] < 90) & (a[..., 2] < 90)
    assert green.sum() > green_bare.sum() + 50
