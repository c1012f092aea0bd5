"""Cost of the look and of the camera resolution: seconds per control step (physics sub-steps +
head RGB-D + wrist depth) for `scene.look` flat / textured at 128², 224² and 256², as ratios to
flat 128² measured in the same run on the same episode.
Usage: python benchmarks/bench_render.py [RECIPE] [--steps N]
"""

from __future__ import annotations

import argparse
import os
import time
from pathlib import Path

os.environ.setdefault("LP_NUM_THREADS", "1")

ROOT = Path(__file__).resolve().parents[1]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("recipe", nargs="?", default=str(ROOT / "recipes" / "quickstart.yaml"))
    ap.add_argument("--steps", type=int, default=60)
    args = ap.parse_args()

    from echo_data.recipe import load_recipe
    from echo_data.scene.sampling import sample_episode
    from echo_data.sounds import SoundLibrary
    from echo_data.world import World

    base = load_recipe(args.recipe)
    spec, _ = sample_episode(base, "train", 0, SoundLibrary.from_recipe(base, Path(args.recipe).resolve().parent))
    ref = None
    for look in ("flat", "textured"):
        for res in (128, 224, 256):
            cams = {k: getattr(base.robot, k).model_copy(update={"width": res, "height": res}) for k in ("head_camera", "wrist_camera")}
            recipe = base.model_copy(update={"robot": base.robot.model_copy(update=cams), "scene": base.scene.model_copy(update={"look": look})})
            w = World(spec, recipe, render=True)
            w.observe()  # the first picture builds the pipeline: not part of the measurement
            t0 = time.perf_counter()
            for _ in range(args.steps):
                w.step(w.robot.last_action())
                w.observe()
            dt = (time.perf_counter() - t0) / args.steps
            w.close()
            ref = ref or dt
            print(f"{look:9s} {res}²: {dt * 1e3:6.1f} ms/step  ratio {dt / ref:4.2f}x vs flat 128²", flush=True)


if __name__ == "__main__":
    main()
