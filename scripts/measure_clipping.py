"""Peak level of real episode tracks (sampled, simulated without cameras, heard): which would
stop a build with ClippingError. One JSON line per episode:

    python scripts/measure_clipping.py
"""

from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np

from echo_data.app.build import default_library
from echo_data.app.pipeline import render_episode_audio, simulate
from echo_data.dataset.manifest import split_sizes
from echo_data.pcm import FULL_SCALE, SCALE
from echo_data.recipe import load_recipe
from echo_data.scene.sampling import SamplingError, sample_episode

RECIPES = Path(__file__).resolve().parent.parent / "recipes"
# (recipe, train episodes, test episodes) measured
PLAN = [("quickstart", 99, 99), ("object_relocation", 4, 0), ("state_transition", 4, 0), ("multi_event", 4, 0)]


def main() -> None:
    for name, n_train, n_test in PLAN:
        recipe = load_recipe(RECIPES / f"{name}.yaml")
        lib = default_library(recipe, RECIPES)
        for split, size in split_sizes(recipe, None).items():
            for i in range(min(size, n_train if split == "train" else n_test)):
                t = time.time()
                for attempt in range(recipe.max_attempts_per_episode):
                    try:
                        spec, _ = sample_episode(recipe, split, i, lib, attempt=attempt)
                    except SamplingError:
                        continue
                    rollout = simulate(spec, recipe, observe=False)
                    if rollout.success:
                        break
                else:
                    print(json.dumps({"recipe": name, "episode": f"{split}-{i}", "status": "no success"}), flush=True)
                    continue
                track, _ = render_episode_audio(spec, rollout, recipe, lib)
                over = int((np.abs(np.rint(np.asarray(track, np.float64) * SCALE)) >= FULL_SCALE).sum())
                print(json.dumps({
                    "recipe": name, "episode": f"{split}-{i}", "setting": spec.setting,
                    "peak": round(float(np.abs(track).max()), 3), "clipped_samples": over,
                    "clipped_fraction": round(over / track.size, 5), "s": round(time.time() - t, 1),
                }), flush=True)


if __name__ == "__main__":
    main()
