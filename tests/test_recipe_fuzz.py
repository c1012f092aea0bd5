"""Recipe mutations at every level of recipes/base.yaml: a missing key, an extra key, a value of
the wrong type, out of range or empty. Each one either is refused in one line that names the
file and a recipe key (exit 2 in the CLI), or loads into a recipe whose first drawn episode does
not contradict it (its setting, sound categories and instances, clutter and materials). Never a
traceback.

The recipe validator and the pure sampler run in-process (a draw is about 0.1 s; the mapping goes
to `recipe_from_mapping`, as `load_recipe` passes it after reading the YAML); a handful of the
refused mutations go through `echo-data build` itself to check the exit code and the one line.
"""

from __future__ import annotations

import copy
import math
import random
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
import yaml
from support.cli import one_line_exit_2

from echo_data.recipe import Recipe, RecipeError, load_recipe, recipe_from_mapping

BASE = Path(__file__).resolve().parents[1] / "recipes" / "base.yaml"
DRAWN = 60  # loaded mutations whose first episode is drawn and checked (cost ~0.1 s each)
THROUGH_CLI = 6  # refused mutations also run through `echo-data build`
Mutation = tuple[str, dict[str, Any]]


def _base() -> dict[str, Any]:
    data = yaml.safe_load(BASE.read_text())
    data["name"] = "fuzz"
    data["splits"] = {"train": 2, "val": 1, "test": 2}
    return data


def _paths(node: Any, prefix: tuple[str, ...] = ()) -> Iterator[tuple[tuple[str, ...], Any]]:
    """Every key path of the recipe (levels and leaves), depth first."""
    if isinstance(node, dict):
        for k, v in node.items():
            yield (*prefix, k), v
            yield from _paths(v, (*prefix, k))


def _set(data: dict[str, Any], path: tuple[str, ...], value: Any, delete: bool = False) -> dict[str, Any]:
    out = copy.deepcopy(data)
    node = out
    for k in path[:-1]:
        node = node[k]
    if delete:
        del node[path[-1]]
    else:
        node[path[-1]] = value
    return out


def _wrong_values(v: Any) -> list[tuple[str, Any]]:
    """Values of the wrong type, out of range, empty or unknown for a value like `v`."""
    out: list[tuple[str, Any]] = [("text", "zz-not-a-value"), ("list", [1, 2]), ("mapping", {"k": 1}), ("null", None), ("true", True)]
    if isinstance(v, (int, float)) and not isinstance(v, bool):
        out += [("negative", -abs(v) - 1), ("huge", abs(v) * 1e6 + 1e6), ("nan", math.nan), ("inf", math.inf), ("zero", 0), ("fraction", 0.5)]
    if isinstance(v, list):
        out += [("empty", [])]
        if v:
            out += [("repeated", [v[0], v[0]]), ("unknown item", [*v[:-1], "zz-unknown"])]
        if len(v) == 2 and all(isinstance(x, (int, float)) for x in v):
            out += [("reversed", [v[1], v[0]]), ("too wide", [v[0] - 100, v[1] + 100]), ("three", [*v, v[1]])]
    if isinstance(v, dict):
        out += [("empty mapping", {})]
        if v:
            k0 = next(iter(v))
            out += [("all zero", {k: 0 for k in v}), ("one unknown key", {**v, "zz_unknown": 1}), ("first negative", {**v, k0: -1})]
    if isinstance(v, str):
        out += [("unknown name", "zz_unknown"), ("empty text", "")]
    return out


def mutations() -> list[Mutation]:
    base = _base()
    out: list[Mutation] = [("<unchanged>", base)]
    levels = [()] + [p for p, v in _paths(base) if isinstance(v, dict)]
    for level in levels:  # an extra key at every level
        node = base
        for k in level:
            node = node[k]
        out.append((f"{'.'.join(level) or '<root>'}: extra key", _set(base, (*level, "zz_extra"), 1)))
    for path, v in _paths(base):
        dotted = ".".join(path)
        out.append((f"{dotted}: missing", _set(base, path, None, delete=True)))
        out += [(f"{dotted}: {what}", _set(base, path, value)) for what, value in _wrong_values(v)]
    random.Random(0).shuffle(out)  # a fixed draw: which loaded ones are sampled is the same every run
    return out


def _refusal_names_a_key(message: str, source: str) -> None:
    assert "\n" not in message and message.startswith(f"{source}: "), message
    key, _, why = message[len(source) + 2 :].partition(": ")
    root = key.split(".")[0]
    assert root in Recipe.model_fields or (why.startswith("unknown key") and key), message  # a recipe key, from the top


def _check_episode(recipe: Recipe) -> bool:
    """Draw the first episode of the recipe's first split (a few attempts if a draw is
    unsolvable) and check it against the recipe; False when every draw was rejected."""
    from echo_data.episode import attempt_draws
    from echo_data.scene.draw import Reject, draw_episode
    from echo_data.sounds import SoundLibrary

    library = SoundLibrary.from_recipe(recipe, BASE.parent)
    split = next(s for s, n in recipe.splits.items() if n > 0)
    for draw, seed in attempt_draws(recipe.seed, split, 0, 0, 3):
        try:
            spec = draw_episode(recipe, split, 0, draw, seed, library)
        except Reject:
            continue
        assert spec.setting in recipe.settings_drawn(), (spec.setting, recipe.setting)
        for event in spec.events:
            assert event.category in recipe.categories_drawn(), (event.category, recipe.events.categories)
            inst = library.get(event.sound_id)
            assert inst.category == event.category and inst.split == ("test" if split == "test" else "train")
        clutter = [o for o in spec.plan.objects if not o.sounding]
        assert len(clutter) <= recipe.objects.distractors[1]
        assert all(o.category in recipe.objects.distractor_shapes for o in clutter)
        floors = set(recipe.scene.floor_materials) | set(recipe.scene.wet_floor_materials or ())
        for room in spec.plan.rooms:
            assert room.wall_material in recipe.scene.wall_materials and room.ceiling_material in recipe.scene.ceiling_materials
            assert room.floor_material in floors
        assert spec.plan.wall_height == recipe.scene.wall_height
        return True
    return False


def test_every_mutation_is_refused_in_one_line_or_draws_a_faithful_episode(tmp_path: Path) -> None:
    refused: list[Mutation] = []
    loaded = drawn = 0
    source = str(tmp_path / "fuzz.yaml")
    for what, data in mutations():
        try:  # the mapping straight to the validator: parsing 900 YAML files would take most of a minute
            recipe = recipe_from_mapping(copy.deepcopy(data), source)
        except RecipeError as e:
            _refusal_names_a_key(str(e), source)
            refused.append((what, data))
            continue
        loaded += 1
        if drawn < DRAWN or what == "<unchanged>":
            try:  # any exception here is a bug: the recipe was accepted
                drawn += _check_episode(recipe)
            except Exception as e:
                pytest.fail(f"{what}: accepted, then the first episode failed: {type(e).__name__}: {e}")
    assert len(refused) > 200 and loaded > 50 and drawn >= DRAWN // 2, (len(refused), loaded, drawn)
    for i, (what, data) in enumerate(refused[:THROUGH_CLI]):  # the real command: exit 2, one line, nothing written
        path = tmp_path / f"m{i}.yaml"
        path.write_text(yaml.safe_dump(data, sort_keys=False))
        out = tmp_path / f"out-{i}"
        one_line_exit_2(["build", str(path), "--out", str(out), "--no-progress"], str(path))
        assert not out.exists(), what


@pytest.mark.parametrize("what", ["<root>: extra key", "robot.head_camera: extra key", "scene.rooms: reversed", "events.categories: all zero", "objects.targets: empty"])
def test_named_mutations_are_refused(what: str, tmp_path: Path) -> None:
    """A few of the drawn mutations by name, so a change to the generator cannot drop them."""
    data = dict(mutations())[what]
    path = tmp_path / "r.yaml"
    path.write_text(yaml.safe_dump(data))
    with pytest.raises(RecipeError) as exc:
        load_recipe(path)
    _refusal_names_a_key(str(exc.value), str(path))
