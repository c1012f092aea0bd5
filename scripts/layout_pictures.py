"""Pictures of the layout families for the README (docs/layouts.png): for an L-shaped room, a
corridor and an open-plan kitchen/living room, the plan from above and a head-camera frame
(1.1 m up, the recipe's camera) looking through the wide opening or along the hall.

Usage: python scripts/layout_pictures.py [RECIPE] [SEED]
"""

from __future__ import annotations

import math
import os
import sys
import tempfile
from pathlib import Path

os.environ.setdefault("LP_NUM_THREADS", "1")
sys.path.insert(0, str(Path(__file__).resolve().parent))

import numpy as np  # noqa: E402
from PIL import Image  # noqa: E402
from readme_pictures import ROOT, _pose, _shot  # noqa: E402

FAMILIES = ("l_shape", "corridor", "open_plan")
TILT = 0.25  # rad down: a view across the space rather than at the floor
SIDE = 384  # px per panel


def _eye(plan) -> tuple[np.ndarray, float]:  # type: ignore[no-untyped-def]
    """Where the camera stands and its yaw: 1.2 m before the wide opening facing through it, or
    0.5 m into a corridor's hall facing along it."""
    if plan.open_doorways:
        dw = plan.doorways[min(plan.open_doorways)]
        a = plan.rooms[dw.rooms[0]].rect.center
        k = 1 if dw.axis == "x" else 0
        s = 1.0 if a[k] > dw.center[k] else -1.0  # room a's side of the wall
        eye = np.array(dw.center, dtype=float)
        eye[k] += 1.2 * s
        yaw = math.atan2(-s, 0.0) if dw.axis == "x" else math.atan2(0.0, -s)
        return np.array([eye[0], eye[1], 1.1]), yaw
    hall = next(r for r in plan.rooms if r.kind == "hall").rect
    if hall.size[0] >= hall.size[1]:
        return np.array([hall.xmin + 0.5, hall.center[1], 1.1]), 0.0
    return np.array([hall.center[0], hall.ymin + 0.5, 1.1]), math.pi / 2


def main() -> None:
    import sapien

    from echo_data.recipe import load_recipe
    from echo_data.scene.build import build_scene
    from echo_data.scene.generate import generate_floorplan_from_seed
    from echo_data.scene.lighting import add_lights
    from echo_data.viz.topdown import draw_topdown
    from echo_data.world import keep_render_alive

    base = load_recipe(sys.argv[1] if len(sys.argv) > 1 else ROOT / "recipes" / "multi_event.yaml")
    seed = int(sys.argv[2]) if len(sys.argv) > 2 else 1
    keep_render_alive()
    cfg = base.robot.head_camera
    plans, views = [], []
    for fam in FAMILIES:
        recipe = base.model_copy(update={"scene": base.scene.model_copy(update={"layouts": (fam,)})})
        plan = generate_floorplan_from_seed(recipe, seed)
        with tempfile.TemporaryDirectory() as tmp:
            draw_topdown(plan, out=Path(tmp) / "plan.png")
            img = Image.open(Path(tmp) / "plan.png").convert("RGB")
        img.thumbnail((SIDE, SIDE))
        panel = Image.new("RGB", (SIDE, SIDE), "white")
        panel.paste(img, ((SIDE - img.width) // 2, (SIDE - img.height) // 2))
        plans.append(np.asarray(panel))
        scene = sapien.Scene()
        add_lights(scene, plan)
        build_scene(scene, plan, recipe)
        cam = scene.add_camera("head", cfg.width, cfg.height, math.radians(cfg.fov_deg), 0.02, 20.0)
        eye, yaw = _eye(plan)
        cam.entity.set_pose(_pose(eye, yaw, TILT))
        views.append(np.asarray(Image.fromarray(_shot(scene, cam)).resize((SIDE, SIDE), Image.NEAREST)))
    grid = np.concatenate([np.concatenate(plans, axis=1), np.concatenate(views, axis=1)], axis=0)
    Image.fromarray(grid).save(ROOT / "docs" / "layouts.png")
    print("wrote docs/layouts.png:", ", ".join(FAMILIES), "seed", seed)


if __name__ == "__main__":
    main()
