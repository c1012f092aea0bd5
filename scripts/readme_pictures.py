"""Pictures for the README: a head-camera frame from each room kind and close-ups of the
sounding objects (docs/rooms.png, docs/objects.png).

Head frames use the head camera's geometry (1.1 m up, tilted 0.45 rad down, the recipe's field
of view and 128² resolution) standing in a room corner looking at its centre; close-ups show
three instances of phone, alarm clock and furby on a table top.
Usage: python scripts/readme_pictures.py [RECIPE]
"""

from __future__ import annotations

import math
import os
import sys
from dataclasses import replace
from pathlib import Path

os.environ.setdefault("LP_NUM_THREADS", "1")

import numpy as np  # noqa: E402
from PIL import Image  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
KINDS = ("living", "kitchen", "bedroom", "bathroom")
HEAD_Z, HEAD_TILT = 1.1, 0.45


def _pose(eye: np.ndarray, yaw: float, pitch: float):
    import sapien

    cy, sy, cp, sp = math.cos(yaw / 2), math.sin(yaw / 2), math.cos(pitch / 2), math.sin(pitch / 2)
    q = [cy * cp, -sy * sp, cy * sp, sy * cp]  # yaw about z, then pitch (down positive) about y
    return sapien.Pose(eye.tolist(), q)


def _shot(scene, cam) -> np.ndarray:
    scene.update_render()
    cam.take_picture()
    return np.clip(cam.get_picture("Color")[..., :3] * 255 + 0.5, 0, 255).astype(np.uint8)


def _closeups(plan) -> list[np.ndarray]:
    """Three instances each of phone, alarm clock and furby on a wooden table by a painted wall."""
    import sapien

    from echo_data.scene.bodies import build_object
    from echo_data.scene.build import add_visual_box
    from echo_data.scene.lighting import add_lights
    from echo_data.scene.objects import object_size
    from echo_data.scene.surfaces import furniture_look, surface_look

    out = []
    for i in range(9):
        cat = ("phone", "alarm", "furby")[i // 3]
        scene = sapien.Scene()
        add_lights(scene, replace(plan, seed=i))
        ent = sapien.Entity()
        body = sapien.render.RenderBodyComponent()
        add_visual_box(body, (0.0, 0.0, 0.375), (0.5, 0.4, 0.375), furniture_look("table", "wooden_door", i), False)
        add_visual_box(body, (-0.6, 0.0, 1.2), (0.05, 1.5, 1.2), surface_look("plasterboard", "living", i), False)
        ent.add_component(body)
        scene.add_entity(ent)
        z = 0.75 + object_size(cat)[2] / 2.0
        yaw = {"phone": 0.4, "alarm": math.pi / 2 - 0.5, "furby": -0.3}[cat]
        obj = replace(plan.objects[0], name=f"closeup_{i}", category=cat, position=(0.0, 0.0, z), yaw=yaw)
        build_object(scene, obj, 1000 + i)
        cam = scene.add_camera("close", 160, 160, math.radians(22.0), 0.02, 20.0)
        eye = np.array([0.45, 0.0, z + 0.2])
        cam.entity.set_pose(_pose(eye, math.pi, math.atan2(0.2, 0.45)))
        out.append(_shot(scene, cam))
    return out


def main() -> None:
    import sapien

    from echo_data.recipe import load_recipe
    from echo_data.scene.build import build_scene
    from echo_data.scene.generate import generate_floorplan_from_seed
    from echo_data.scene.lighting import add_lights
    from echo_data.world import keep_render_alive

    recipe = load_recipe(sys.argv[1] if len(sys.argv) > 1 else ROOT / "recipes" / "multi_event.yaml")
    keep_render_alive()
    cfg = recipe.robot.head_camera
    frames: dict[str, np.ndarray] = {}
    for seed in range(60):
        plan = generate_floorplan_from_seed(recipe, seed)
        want = [r for r in plan.rooms if r.kind in KINDS and r.kind not in frames]
        if not want:
            continue
        scene = sapien.Scene()
        add_lights(scene, plan)
        build_scene(scene, plan, recipe)
        for r in want:
            cam = scene.add_camera("head", cfg.width, cfg.height, math.radians(cfg.fov_deg), 0.02, 20.0)
            corner = np.array([r.rect.xmin + 0.5, r.rect.ymin + 0.5, HEAD_Z])
            yaw = math.atan2(r.rect.center[1] - corner[1], r.rect.center[0] - corner[0])
            cam.entity.set_pose(_pose(corner, yaw, HEAD_TILT))
            frames[r.kind] = _shot(scene, cam)
        if len(frames) == len(KINDS):
            break
    closeups = _closeups(plan)
    row = np.concatenate([np.asarray(Image.fromarray(frames[k]).resize((256, 256), Image.NEAREST)) for k in KINDS if k in frames], axis=1)
    Image.fromarray(row).save(ROOT / "docs" / "rooms.png")
    grid = np.concatenate([np.concatenate(closeups[i : i + 3], axis=1) for i in range(0, 9, 3)], axis=0)
    Image.fromarray(grid).save(ROOT / "docs" / "objects.png")
    print("rooms:", [k for k in KINDS if k in frames], "close-ups:", len(closeups))


if __name__ == "__main__":
    main()
