"""Recipe loading: defaults, extends, hashing, and one-line errors naming file and key."""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import numpy as np
import pytest

from echo_data.recipe import RecipeError, load_recipe, recipe_from_mapping

RECIPES = Path(__file__).resolve().parents[1] / "recipes"


SHIPPED = [p for p in (*sorted(RECIPES.glob("*.yaml")), *sorted(RECIPES.parent.glob("studies/*/recipes/*.yaml")))
           if p.name != "base.yaml"]  # base.yaml: the defaults the others extend, no episodes of its own


@pytest.mark.parametrize("path", SHIPPED, ids=lambda p: str(p.relative_to(RECIPES.parent)))
def test_shipped_recipes_load(path: Path) -> None:
    """Every recipe users start from (recipes/) and every study's: each loads, named after its file."""
    r = load_recipe(path)
    assert r.name == path.stem
    assert sum(r.splits.values()) > 0


def test_paper_episode_counts() -> None:
    assert load_recipe(RECIPES / "object_relocation.yaml").splits == {"train": 660, "test": 222}
    assert load_recipe(RECIPES / "state_transition.yaml").splits == {"train": 660, "test": 222}
    assert load_recipe(RECIPES / "multi_event.yaml").splits == {"train": 660, "test": 355}
    full = load_recipe(RECIPES / "stmm_1_9k.yaml")
    assert full.splits == {"train": 1980, "test": 799}


def test_composition_interleave_keeps_exact_counts() -> None:
    r = load_recipe(RECIPES / "stmm_1_9k.yaml")
    rng = np.random.default_rng(0)
    counts: dict[str, int] = {}
    for i in range(r.splits["test"]):
        s = r.setting_for("test", i, rng)
        counts[s] = counts.get(s, 0) + 1
    assert counts == {"object_relocation": 222, "state_transition": 222, "multi_event": 355}
    first = [r.setting_for("test", i, rng) for i in range(12)]
    assert set(first) == {"object_relocation", "state_transition", "multi_event"}


def test_extends_merges_and_overrides(tmp_path: Path) -> None:
    (tmp_path / "a.yaml").write_text("name: a\nseed: 5\nscene:\n  rooms: [2, 3]\n  wall_height: 2.7\n")
    (tmp_path / "b.yaml").write_text("extends: a.yaml\nname: b\nscene:\n  rooms: [3, 5]\n")
    r = load_recipe(tmp_path / "b.yaml")
    assert (r.name, r.seed, r.scene.rooms, r.scene.wall_height) == ("b", 5, (3, 5), 2.7)


def test_hash_changes_with_content() -> None:
    a = recipe_from_mapping({"name": "x"})
    b = recipe_from_mapping({"name": "x", "seed": 1})
    assert a.content_hash() == recipe_from_mapping({"name": "x"}).content_hash()
    assert a.content_hash() != b.content_hash()
    # outputs.max_frames: null (the default) keeps the hash recipes had before the key existed,
    # so older datasets still resume; a cut changes it
    d = a.model_dump(mode="json")
    del d["outputs"]["max_frames"]
    del d["experts"]
    del d["sounds"]["fresh_train_instances"]
    del d["robot"]["action_space"]
    del d["robot"]["grasp"]
    assert a.content_hash() == hashlib.sha256(json.dumps(d, sort_keys=True, separators=(",", ":")).encode()).hexdigest()
    assert recipe_from_mapping({"name": "x", "outputs": {"max_frames": 10}}).content_hash() != a.content_hash()
    assert recipe_from_mapping({"name": "x", "sounds": {"fresh_train_instances": True}}).content_hash() != a.content_hash()
    # experts.action_noise: 0 (the default) likewise keeps the hash; DART noise changes it
    assert recipe_from_mapping({"name": "x", "experts": {"action_noise": 0}}).content_hash() == a.content_hash()
    assert recipe_from_mapping({"name": "x", "experts": {"action_noise": 1}}).content_hash() != a.content_hash()
    assert recipe_from_mapping({"name": "x", "experts": {"perturbation": {"position_cm": 1}}}).content_hash() != a.content_hash()
    assert recipe_from_mapping({"name": "x", "robot": {"action_space": "joint"}}).content_hash() == a.content_hash()
    # experts.handover_noise: 0 keeps it too (the exact interaction pose, as before the key existed)
    assert recipe_from_mapping({"name": "x", "experts": {"handover_noise": 0}}).content_hash() == a.content_hash()
    assert recipe_from_mapping({"name": "x", "experts": {"handover_noise": 0.5}}).content_hash() != a.content_hash()
    # robot.grasp: physical (the default) likewise; Habitat's magic grasp changes it
    assert recipe_from_mapping({"name": "x", "robot": {"grasp": "physical"}}).content_hash() == a.content_hash()
    assert recipe_from_mapping({"name": "x", "robot": {"grasp": "magic"}}).content_hash() != a.content_hash()


@pytest.mark.parametrize(
    "text, key",
    [
        ("name: x\nscene:\n  roomz: [2, 3]\n", "scene.roomz: unknown key"),
        ("name: x\nscene:\n  rooms: [5, 2]\n", "scene.rooms"),
        ("name: x\nscene:\n  rooms: [2, 9]\n", "scene.rooms"),
        ("name: x\nacoustics:\n  sample_rate: fast\n", "acoustics.sample_rate"),
        ("name: x\nrobot:\n  physics_hz: 100\n  control_hz: 30\n", "robot"),
        ("name: x\nscene:\n  wall_materials: [cheese]\n", "scene.wall_materials"),
        ("seed: 1\n", "name: required key is missing"),
        ("name: x\nsplits: {train: -1}\n", "splits"),
        ("name: x\nsounds:\n  folders: {phone: nowhere}\n", "sounds.folders.phone"),
        ("name: x\nscene: [1, 2\n", "malformed YAML"),
        ("name: x\noutputs:\n  max_frames: 0\n", "outputs.max_frames"),
        ("name: x\noutputs:\n  max_frames: ten\n", "outputs.max_frames"),
        ("name: x\noutputs:\n  max_frames: 2.5\n", "outputs.max_frames"),
        ("name: x\noutputs:\n  max_frames: true\n", "outputs.max_frames"),
        ("name: x\nsounds:\n  fresh_train_instances: maybe\n", "sounds.fresh_train_instances"),
        ("name: x\nsounds:\n  builtin: false\n  fresh_train_instances: true\n", "sounds.fresh_train_instances"),
        ("- a\n- b\n", "must be a mapping"),
        ("name: x\nexperts:\n  action_noise: -0.5\n", "experts.action_noise"),
        ("name: x\nexperts:\n  action_noise: lots\n", "experts.action_noise"),
        ("name: x\nexperts:\n  handover_noise: 1.5\n", "experts.handover_noise"),
        ("name: x\nexperts:\n  action_nosie: 1\n", "experts.action_nosie: unknown key"),
        ("name: x\nexperts:\n  perturbation: {position_cm: -1}\n", "experts.perturbation.position_cm"),
        ("name: x\nexperts:\n  perturbation: {rotation: 2}\n", "experts.perturbation.rotation: unknown key"),
        ("name: x\nrobot:\n  action_space: cartesian\n", "robot.action_space"),
    ],
)
def test_bad_recipes_give_one_line_errors(tmp_path: Path, text: str, key: str) -> None:
    f = tmp_path / "bad.yaml"
    f.write_text(text)
    with pytest.raises(RecipeError) as e:
        load_recipe(f)
    msg = str(e.value)
    assert "\n" not in msg
    assert str(f.resolve()) in msg or str(f) in msg
    assert key in msg


def test_missing_file_and_cycle(tmp_path: Path) -> None:
    with pytest.raises(RecipeError, match="file not found"):
        load_recipe(tmp_path / "none.yaml")
    (tmp_path / "a.yaml").write_text("extends: b.yaml\nname: a\n")
    (tmp_path / "b.yaml").write_text("extends: a.yaml\nname: b\n")
    with pytest.raises(RecipeError, match="circular"):
        load_recipe(tmp_path / "a.yaml")
