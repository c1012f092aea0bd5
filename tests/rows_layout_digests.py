"""Digests of episodes and floor plans made by the row layout, for `test_scene_layouts`.

`python tests/rows_layout_digests.py` rewrites `tests/data/rows_layout_digests.json`. It was
run once on the generator before the layout families existed (commit c000082); the test
recomputes the digests with `scene.layouts: [rows]` and must find the same values, so recipes
that ask for rows keep their episodes draw for draw.
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path
from typing import Any

from echo_data.recipe import Recipe, load_recipe
from echo_data.scene.generate import generate_floorplan_from_seed
from echo_data.scene.sampling import sample_episode
from echo_data.sounds.library import SoundLibrary

ROOT = Path(__file__).resolve().parent.parent
FIXTURE = ROOT / "tests" / "data" / "rows_layout_digests.json"
RECIPES = ("recipes/quickstart.yaml", "studies/navigation_ablation/recipes/bc_navigate.yaml")
PLAN_SEEDS = range(40)
EPISODES = (("train", 0), ("train", 1), ("train", 2), ("test", 0), ("test", 1), ("test", 2))


def digest(d: dict[str, Any]) -> str:
    """sha256 of the canonical JSON of a spec or plan dict (floats as Python writes them)."""
    return hashlib.sha256(json.dumps(d, sort_keys=True).encode()).hexdigest()


def _as_drawn_then(spec: dict[str, Any]) -> dict[str, Any]:
    """The spec as the fixture's generator wrote it: fields added since (each event's `level_db`,
    carried in the spec since the renderer was unified, drawn from the same stream as before)
    are left out, so the digests still compare the draws themselves."""
    return {**spec, "events": [{k: v for k, v in e.items() if k != "level_db"} for e in spec["events"]]}


def compute(recipe: Recipe) -> dict[str, Any]:
    lib = SoundLibrary.from_recipe(recipe)
    plans = {str(s): digest(generate_floorplan_from_seed(recipe, s).to_dict()) for s in PLAN_SEEDS}
    episodes = {f"{sp}-{i}": digest(_as_drawn_then(sample_episode(recipe, sp, i, lib)[0].to_dict())) for sp, i in EPISODES}
    return {"plans": plans, "episodes": episodes}


def as_before(recipe: Recipe) -> Recipe:
    """`recipe` with the keys that keep the generator as it was before the layout families:
    rows only, wet-room floors as drawn, objects at their base size."""
    scene = recipe.scene.model_copy(update={"layouts": ("rows",), "wet_floor_materials": None})
    objects = recipe.objects.model_copy(update={"size_variants": False})
    return recipe.model_copy(update={"scene": scene, "objects": objects})


def main() -> None:
    """Rewrite the fixture (with `as_before`, a rerun on today's code must give the same bytes)."""
    out = {r: compute(as_before(load_recipe(ROOT / r))) for r in RECIPES}
    FIXTURE.write_text(json.dumps(out, indent=1, sort_keys=True) + "\n")


if __name__ == "__main__":
    main()
