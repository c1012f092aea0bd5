"""Pick (then Place) from a random point of Navigate's success region, on real episodes.

A learned Navigate hands over short and off-axis; the manipulation experts must start from
anywhere in `skills.success.navigate_success`'s region. Per train episode: the scripted Navigate
runs, then the base is set to a random free point 0.3-1.5 m from the object's interaction pose,
heading at the object within 14 deg (the region: 1.5 m, 15 deg), drawn from a generator seeded
by the episode index, and Pick and Place run from there (physics only, no rendering: the experts
read the world, as in tests/test_pick_place_experts.py).

    python studies/experts/pick_handover.py recipes/object_relocation.yaml -n 20

Development tool: the train split only. Prints one line per episode and a JSON summary.
"""

from __future__ import annotations

import argparse
import json
import math
import os
from pathlib import Path
from typing import Any

import numpy as np

os.environ.setdefault("LP_NUM_THREADS", "1")

RADIUS = (0.3, 1.5)  # m from the interaction pose
HEADING = math.radians(14)  # rad off the bearing to the object
TRIES = 500


def run_skill(world: Any, call: Any, spec: Any) -> Any:
    """Apply every action the skill's expert yields (either form); returns its SkillOutcome."""
    from echo_data.records import EE_ACTION_DIM
    from echo_data.skill_table import skill

    gen = skill(call.skill).expert_fn()(world, call, spec)
    try:
        while True:
            a = np.asarray(next(gen), dtype=np.float32)
            world.step(world.robot.ee.to_joint(a) if a.shape == (EE_ACTION_DIM,) else a)
    except StopIteration as stop:
        return stop.value


def handover(world: Any, name: str, rng: np.random.Generator) -> tuple[float, float] | None:
    """Set the base at a random point of Navigate's success region for object `name`; (distance
    from the interaction pose, from the object) or None when no free point was drawn."""
    from echo_data.scene.nav import interaction_pose
    from echo_data.skills.navigate import current_grid
    from echo_data.skills.success import navigate_success

    grid = current_grid(world)
    sx, sy, _ = interaction_pose(world.plan, name, grid=grid)
    o = world.plan.object_by_name(name).position
    for _ in range(TRIES):
        r, th = rng.uniform(*RADIUS), rng.uniform(-math.pi, math.pi)
        x, y = sx + r * math.cos(th), sy + r * math.sin(th)
        if not grid.is_free(x, y):
            continue
        world.robot.set_base_pose(x, y, math.atan2(o[1] - y, o[0] - x) + rng.uniform(-1.0, 1.0) * HEADING)
        if navigate_success(world, name):
            return r, math.hypot(o[0] - x, o[1] - y)
    return None


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("recipe")
    ap.add_argument("-n", type=int, default=10)
    args = ap.parse_args()

    from echo_data.recipe import load_recipe
    from echo_data.scene.sampling import sample_episode
    from echo_data.sounds import SoundLibrary
    from echo_data.world import World

    recipe = load_recipe(Path(args.recipe))
    library = SoundLibrary.from_recipe(recipe, Path(args.recipe).resolve().parent)
    counts = {"Pick": [0, 0], "Place": [0, 0]}
    for index in range(args.n):
        spec, _ = sample_episode(recipe, "train", index, library)
        k = next(i for i, c in enumerate(spec.chain) if c.skill == "Pick")
        world = World(spec, recipe, render=False)
        try:
            for call in spec.chain[:k]:
                run_skill(world, call, spec)
            start = handover(world, spec.chain[k].target, np.random.default_rng(index))
            if start is None:
                print(index, "no free start drawn")
                continue
            pick = run_skill(world, spec.chain[k], spec)
            counts["Pick"][0] += int(pick.success)
            counts["Pick"][1] += 1
            line = f"{index} start {start[0]:.2f} m from the interaction pose, {start[1]:.2f} m from the object: Pick {pick.success} {pick.reason}"
            if pick.success and k + 1 < len(spec.chain) and spec.chain[k + 1].skill == "Place":
                place = run_skill(world, spec.chain[k + 1], spec)
                counts["Place"][0] += int(place.success)
                counts["Place"][1] += 1
                line += f", Place {place.success} {place.reason}"
            print(line, flush=True)
        finally:
            world.close()
    print(json.dumps({s: {"successes": k_, "n": n} for s, (k_, n) in counts.items()}))


if __name__ == "__main__":
    main()
