"""Visual probe: can a small CNN tell phone / alarm clock / furby / distractor apart from what a
head camera sees of them, on homes it was not trained on — and how much of that is appearance?

Crops: for each generated home (train seeds, then other test seeds) the apartment is built with
its textures and lights, its objects are re-cast so the four classes are balanced (each object
spot holds in turn a phone, an alarm, a furby or a random distractor, resting on its receptacle),
and a camera renders each object from head-like viewpoints (0.45-0.75 m away, 0.4-0.7 m above
it, any azimuth; a narrow field of view so the crop is the object and a little of its
surroundings: what a crop of the 128² head frame around the object holds, at 48² pixels).
Viewpoints inside or behind a wall or a piece of furniture are redrawn (a crop *around an
object* shows it). The control renders the same shapes, poses and scenes with every object in one grey (`mono`).
Usage: python studies/visual_probe/bench_visual_probe.py [-n TRAIN_HOMES] [--test N] [--epochs E]
"""

from __future__ import annotations

import argparse
import math
import os
import time
from dataclasses import replace
from pathlib import Path

os.environ.setdefault("LP_NUM_THREADS", "1")

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
CLASSES = ("phone", "alarm", "furby", "distractor")
CROP = 48
MONO = (0.6, 0.6, 0.6)
FOV_DEG = 16.0
DISTANCE = (0.45, 0.75)  # m, horizontal, camera to object
HEIGHT = (0.4, 0.7)  # m, camera above the object


def _look_at(eye: np.ndarray, target: np.ndarray):  # -> sapien.Pose (SAPIEN camera: x forward, z up)
    import sapien

    f = target - eye
    f /= np.linalg.norm(f)
    left = np.cross([0.0, 0.0, 1.0], f)
    left /= np.linalg.norm(left)
    up = np.cross(f, left)
    m = np.eye(4)
    m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3] = f, left, up, eye
    return sapien.Pose(m)


def _clear(eye: np.ndarray, target: np.ndarray, blockers: list) -> bool:
    """No wall or furniture block between the camera and the object (sampled along the ray)."""
    for t in np.linspace(0.0, 0.9, 40):
        x, y, z = eye + t * (target - eye)
        if any(r.xmin <= x <= r.xmax and r.ymin <= y <= r.ymax and z < top for r, top in blockers):
            return False
    return True


def collect(recipe_path: Path, seeds: list[int], views: int, mono: bool) -> tuple[np.ndarray, np.ndarray]:
    """(crops uint8 (N, CROP, CROP, 3), labels (N,)) from the homes of `seeds`."""
    import sapien

    from echo_data.recipe import load_recipe
    from echo_data.scene.bodies import build_object
    from echo_data.scene.build import build_statics
    from echo_data.scene.generate import generate_floorplan_from_seed
    from echo_data.scene.lighting import add_lights
    from echo_data.scene.objects import DISTRACTOR_CATEGORIES, instance_scale, object_size
    from echo_data.world import keep_render_alive

    recipe = load_recipe(recipe_path)
    keep_render_alive()
    xs: list[np.ndarray] = []
    ys: list[int] = []
    for seed in seeds:
        plan = generate_floorplan_from_seed(recipe, seed)
        rng = np.random.default_rng([seed, 7])
        scene = sapien.Scene()
        add_lights(scene, plan)
        build_statics(scene, plan)
        cam = scene.add_camera("probe", CROP, CROP, math.radians(FOV_DEG), 0.02, 20.0)
        solid = [w.footprint.expanded(0.1) for w in plan.walls] + [f.footprint.expanded(0.1) for f in plan.furniture]
        blockers = [(w.footprint, w.height) for w in plan.walls] + [(f.footprint, f.top_z) for f in plan.furniture]
        for k, o in enumerate(plan.objects):
            label = (k + seed) % len(CLASSES)
            cat = CLASSES[label] if label < 3 else str(rng.choice(DISTRACTOR_CATEGORIES))
            bottom = o.position[2] - object_size(o.category, o.scale)[2] / 2.0
            scale = instance_scale(cat, o.name, seed) if recipe.objects.size_variants else 1.0  # as the dataset draws it
            z = bottom + object_size(cat, scale)[2] / 2.0
            obj = replace(o, category=cat, position=(o.position[0], o.position[1], z), yaw=float(rng.uniform(0, 2 * math.pi)), scale=scale)
            ent = build_object(scene, obj, seed, mono=MONO if mono else None)
            target = np.array(obj.position)
            for _ in range(views):
                for _try in range(20):  # a viewpoint in the air, not inside a wall or a cupboard
                    az = rng.uniform(0, 2 * math.pi)
                    d, h = rng.uniform(*DISTANCE), rng.uniform(*HEIGHT)
                    eye = target + np.array([d * math.cos(az), d * math.sin(az), h])
                    if not any(r.xmin <= eye[0] <= r.xmax and r.ymin <= eye[1] <= r.ymax for r in solid) and _clear(eye, target, blockers):
                        break
                cam.entity.set_pose(_look_at(eye, target))
                scene.update_render()
                cam.take_picture()
                rgba = cam.get_picture("Color")
                xs.append(np.clip(rgba[..., :3] * 255.0 + 0.5, 0, 255).astype(np.uint8))
                ys.append(label)
            scene.remove_entity(ent)
    return np.stack(xs), np.asarray(ys)


def train_probe(x: np.ndarray, y: np.ndarray, xt: np.ndarray, yt: np.ndarray, epochs: int, seed: int = 0) -> float:
    """Train a 3-conv CNN on (x, y); accuracy on (xt, yt)."""
    import torch
    from torch import nn

    torch.manual_seed(seed)
    torch.set_num_threads(1)
    net = nn.Sequential(
        nn.Conv2d(3, 16, 3, padding=1), nn.ReLU(), nn.MaxPool2d(2),
        nn.Conv2d(16, 32, 3, padding=1), nn.ReLU(), nn.MaxPool2d(2),
        nn.Conv2d(32, 64, 3, padding=1), nn.ReLU(), nn.AdaptiveAvgPool2d(1),
        nn.Flatten(), nn.Linear(64, len(CLASSES)),
    )

    def prep(a: np.ndarray) -> torch.Tensor:
        return torch.from_numpy(a).permute(0, 3, 1, 2).float() / 255.0 - 0.5

    tx, ty = prep(x), torch.from_numpy(y).long()
    opt = torch.optim.Adam(net.parameters(), lr=3e-3)
    g = torch.Generator().manual_seed(seed)
    for _ in range(epochs):
        for idx in torch.randperm(len(tx), generator=g).split(32):
            batch = tx[idx]
            if torch.rand(1, generator=g).item() < 0.5:
                batch = batch.flip(3)  # a mirrored view is the same object
            loss = nn.functional.cross_entropy(net(batch), ty[idx])
            opt.zero_grad()
            loss.backward()
            opt.step()
    with torch.no_grad():
        pred = net(prep(xt)).argmax(1).numpy()
    return float((pred == yt).mean())


def run(recipe_path: Path, train_homes: int, test_homes: int, views: int, epochs: int) -> dict[str, float]:
    """Probe accuracy on held-out homes, textured and single-colour."""
    train = list(range(train_homes))
    test = list(range(10_000, 10_000 + test_homes))  # other seeds: homes never seen in training
    out: dict[str, float] = {}
    for name, mono in (("textured", False), ("mono", True)):
        x, y = collect(recipe_path, train, views, mono)
        xt, yt = collect(recipe_path, test, views, mono)
        out[name] = train_probe(x, y, xt, yt, epochs)
        out[f"{name}_n"] = float(len(x))
        out[f"{name}_nt"] = float(len(xt))
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("recipe", nargs="?", default=str(ROOT / "recipes" / "object_relocation.yaml"))
    ap.add_argument("-n", type=int, default=150, help="train homes")
    ap.add_argument("--test", type=int, default=30, help="test homes (other seeds)")
    ap.add_argument("--views", type=int, default=8, help="views per object")
    ap.add_argument("--epochs", type=int, default=30)
    args = ap.parse_args()
    t0 = time.perf_counter()
    res = run(Path(args.recipe), args.n, args.test, args.views, args.epochs)
    print(f"train crops {res['textured_n']:.0f}, test crops {res['textured_nt']:.0f} (classes: {', '.join(CLASSES)}; chance 0.25)")
    print(f"textured + lit objects : accuracy {res['textured']:.3f} on held-out homes")
    print(f"single-colour (mono)   : accuracy {res['mono']:.3f} on held-out homes")
    print(f"{time.perf_counter() - t0:.0f} s")


if __name__ == "__main__":
    main()
