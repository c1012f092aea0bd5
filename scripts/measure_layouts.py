"""Generation and sampling success per layout family (issue 12: layouts stay solvable).

    python scripts/measure_layouts.py recipes/stmm_1_9k.yaml -n 200

For each family in `scene.layouts` (one at a time): the share of apartment draws the generator
accepts on the first try (`_try_generate`, before its own retries), and the share of episodes
(train indices 0..n-1) `sample_episode` finds solvable within the recipe's attempt budget, with
the mean attempts and the rejections by reason (the checks in scene/sampling.py and nav.py).
"""

from __future__ import annotations

import argparse
import collections
import json

import numpy as np

from echo_data.recipe import load_recipe
from echo_data.scene import generate
from echo_data.scene.sampling import SamplingError, sample_episode
from echo_data.sounds.library import SoundLibrary


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("recipe")
    ap.add_argument("-n", type=int, default=200)
    args = ap.parse_args()
    base = load_recipe(args.recipe)
    lib = SoundLibrary.from_recipe(base)
    out = {}
    for fam in base.scene.layouts:
        recipe = base.model_copy(update={"scene": base.scene.model_copy(update={"layouts": (fam,)})})
        first = sum(generate._try_generate(recipe, np.random.default_rng(s), s, fam) is not None for s in range(args.n))
        ok, attempts, reasons = 0, [], collections.Counter()
        for i in range(args.n):
            try:
                spec, counts = sample_episode(recipe, "train", i, lib)
                ok += 1
                attempts.append(spec.attempt + 1)
            except SamplingError as e:
                counts = e.counts
            reasons.update(counts)
        out[fam] = {
            "plans_first_try": first / args.n,
            "episodes_solvable": ok / args.n,
            "mean_attempts": float(np.mean(attempts)) if attempts else None,
            "rejections": dict(reasons),
        }
        print(fam, json.dumps(out[fam]), flush=True)


if __name__ == "__main__":
    main()
